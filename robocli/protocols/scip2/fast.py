"""SCIP 2.0 through the C core: the reply framer and the whole-scan decoder.

:func:`reply_framer` is ``robocli.core.Framer("scip2")`` (rules in
:mod:`robocli.protocols.scip2.framing`, whose pure-Python :class:`ReplyFramer` gives the same
blocks and counters). :func:`decode_scan` gives the same :class:`ScanReply` as the pure-Python
:func:`robocli.protocols.scip2.decode_scan` and raises the same errors, but decodes the data
lines in C (``rc_scip_decode``: each line's length and sum checked, the sum chars skipped,
values straddling lines joined) straight into a NumPy ``uint32`` array.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from robocli._core import ffi, lib
from robocli.core import Framer
from robocli.errors import ChecksumError, FramingError
from robocli.protocols.scip2.replies import ScanReply, scan_header
from robocli.protocols.scip2.wire import MAX_BLOCK

if TYPE_CHECKING:
    import numpy as np
    import numpy.typing as npt

_ERRORS: dict[int, tuple[type[FramingError], str]] = {
    lib.RC_SCIP_EGARBAGE: (FramingError, "non-printable byte (garbage)"),
    lib.RC_SCIP_ELINE: (
        FramingError,
        "data line of the wrong length or unterminated: truncated block",
    ),
    lib.RC_SCIP_ECHECKSUM: (ChecksumError, "data line checksum mismatch"),
    lib.RC_SCIP_ECOUNT: (
        FramingError,
        "data chars do not make the expected values: truncated block",
    ),
    lib.RC_SCIP_ECHAR: (FramingError, "encoded char outside 0..o"),
}


def reply_framer(max_block: int = MAX_BLOCK) -> Framer:
    """A C framer of SCIP 2.0 reply blocks (``feed(bytes) -> [block, ...]``, ``stats``)."""
    return Framer("scip2", max_block)


def decode_data(
    lines: bytes | bytearray | memoryview, width: int, count: int, check: bool = True
) -> npt.NDArray[np.uint32]:
    """``count`` values of ``width`` (2, 3, 4) chars from the data lines of a scan (the bytes
    after the timestamp line, without the final empty line), each line's sum checked unless
    ``check`` is False. Errors: :class:`ChecksumError`, :class:`FramingError`."""
    data = bytes(lines)
    return _decode(data, 0, len(data), width, count, check)


def _decode(
    data: bytes, start: int, stop: int, width: int, count: int, check: bool
) -> npt.NDArray[np.uint32]:
    """Decode ``data[start:stop]`` without copying it (cffi borrows the bytes' buffer)."""
    import numpy as np

    if width not in (2, 3, 4) or count < 0 or not 0 <= start <= stop <= len(data):
        raise ValueError("width must be 2, 3 or 4, count >= 0, and the span inside the data")
    out = np.empty(count, dtype=np.uint32)
    err_at = ffi.new("size_t *")
    src = ffi.from_buffer("unsigned char[]", data)
    dst = ffi.from_buffer("unsigned int[]", out)
    n = stop - start
    rc = lib.rc_scip_decode(src + start, n, width, 1 if check else 0, dst, count, err_at)
    if rc != lib.RC_SCIP_OK:
        kind, what = _ERRORS.get(rc, (FramingError, f"error {rc}"))
        raise kind(f"SCIP scan data: {what} (at byte {int(err_at[0])} of {n})")
    return out


def decode_scan(block: bytes | bytearray | memoryview, check: bool = True) -> ScanReply:
    """Decode a whole scan reply (GD/GS/GE, MD/MS/ME frame) with the C decoder: same result
    and same errors as the pure-Python :func:`robocli.protocols.scip2.decode_scan`."""
    data = bytes(block)
    if len(data) > MAX_BLOCK:
        raise FramingError(f"SCIP reply of {len(data)} B exceeds {MAX_BLOCK} B")
    end = len(data) - 2 if data.endswith(b"\n\r\n") else len(data) - 1
    i1 = data.find(b"\n")
    i2 = data.find(b"\n", i1 + 1) if i1 >= 0 else -1
    i3 = data.find(b"\n", i2 + 1) if i2 >= 0 else -1
    if i3 < 0 or i3 >= end or not data.endswith(b"\n\n") and not data.endswith(b"\n\r\n"):
        # no data lines (a refusal, an acknowledgement, a truncated block): the reference
        # parser gives the right error
        scan_header(data, check)
        raise FramingError(f"SCIP reply {data[:40]!r}: no data lines: truncated block")
    reply, echo, ts = scan_header(data[: i3 + 1] + b"\n", check)
    per_step = 2 if echo.intensity else 1
    values = _decode(data, i3 + 1, end, echo.width, echo.count * per_step, check)
    if per_step == 2:
        ranges, intensities = values[::2].copy(), values[1::2].copy()
    else:
        ranges, intensities = values, None
    return ScanReply(
        reply.echo, echo.command, reply.status, ts, echo.start, echo.end, echo.cluster,
        echo.remaining, ranges, intensities, echo.tag,
    )  # fmt: skip
