"""SCIP 2.0 replies: one reply block (echo, status, body, empty line) split and checked by
:func:`parse_reply`, ``KEY:value;sum`` bodies (VV/PP/II) read by :func:`parse_info`, scans
(GD/GS/GE, MD/MS/ME frames) decoded by :func:`decode_scan` (the pure-Python reference of the
C decoder), and the simulator's side: :func:`build_reply`, :func:`build_info`,
:func:`build_scan`. Part of :mod:`robocli.protocols.scip2` (import from there).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from robocli.errors import ChecksumError, FramingError, ProtocolError
from robocli.protocols.scip2.commands import ScanEcho, parse_scan_echo
from robocli.protocols.scip2.wire import (
    LF,
    MAX_BLOCK,
    ScipStatusError,
    check_line,
    checksum,
    data_lines,
    decode_value,
    encode_value,
    encode_values,
    is_success,
    join_data_lines,
    strip_eol,
    with_sum,
)

if TYPE_CHECKING:
    import numpy as np
    import numpy.typing as npt


@dataclass(frozen=True)
class Reply:
    """One reply block. ``status`` is the 2-char status (``"00"``), or the single char of a
    SCIP 1.1 reply / of the ``SCIP2.0`` switch (``"0"``, ``"E"``); ``body`` holds the lines
    after the status, EOL stripped, sums still on."""

    echo: bytes
    status: str
    body: tuple[bytes, ...]

    @property
    def command(self) -> str:
        """The request's symbol as echoed (``"GD"``; ``"SCIP2.0"`` for the switch)."""
        return "SCIP2.0" if self.echo == b"SCIP2.0" else self.echo[:2].decode("ascii", "replace")

    @property
    def ok(self) -> bool:
        """Whether the status is a success for the command (``SCIP2.0``: ``0``)."""
        if self.command == "SCIP2.0":
            return self.status == "0"
        return is_success(self.command, self.status)

    def raise_for_status(self) -> Reply:
        """This reply when :attr:`ok`, else :class:`ScipStatusError`."""
        if not self.ok:
            raise ScipStatusError(self.command, self.status)
        return self


def split_lines(block: bytes | bytearray | memoryview) -> list[bytes]:
    """The lines of one reply block (EOL stripped), without the final empty line; a block
    that does not end in an empty line is a truncated block (:class:`FramingError`)."""
    data = bytes(block)
    if len(data) > MAX_BLOCK:
        raise FramingError(f"SCIP reply of {len(data)} B exceeds {MAX_BLOCK} B")
    lines = [strip_eol(x) for x in data.split(LF)]
    # "a\nb\n\n".split -> [a, b, "", ""]: the last two are the block end; a CR is an end of
    # line only before its LF ("...\n\n\r" is cut, as the C decoder says)
    if len(lines) < 3 or lines[-1] != b"" or lines[-2] != b"" or not data.endswith(LF):
        raise FramingError(f"SCIP reply {data[:40]!r}: not ended by an empty line (truncated)")
    lines = lines[:-2]
    if any(not line for line in lines):
        raise FramingError(f"SCIP reply {data[:40]!r}: empty line inside the reply")
    for line in lines:
        if any(c < 0x20 or c > 0x7E for c in line):
            raise FramingError(f"SCIP reply line {line[:40]!r}: non-printable byte (garbage)")
    return lines


def parse_reply(block: bytes | bytearray | memoryview, check: bool = True) -> Reply:
    """Split one reply block into echo, status and body; the status sum is checked (unless
    ``check`` is False). A 1-char status (SCIP 1.1, or the switch's bare ``0``) has no sum."""
    lines = split_lines(block)
    if len(lines) < 2:
        raise FramingError(f"SCIP reply {bytes(block)[:40]!r}: no status line")
    echo, status_line = lines[0], lines[1]
    if len(status_line) == 1:
        status = status_line
    elif len(status_line) == 3:
        status = check_line(status_line, "status") if check else status_line[:2]
    else:
        raise FramingError(f"SCIP status line {status_line!r}: expected 2 chars and a sum")
    return Reply(echo, status.decode("ascii"), tuple(lines[2:]))


def _info_sum_ok(line: bytes) -> bool:
    """``KEY:value;S``: the sum covers ``KEY:value`` (WIKI, HL); UL also accepts it over
    ``KEY:value;``; UTM-30LX reportedly leaves a ``<-...`` comment tail out of it."""
    content, got = line[:-1], line[-1]
    if got == checksum(content[:-1]) or got == checksum(content):
        return True
    cut = content.find(b"<-")
    return cut > 0 and got == checksum(content[:cut])


def parse_info(lines: Iterable[bytes], check: bool = True) -> dict[str, str]:
    """``{KEY: value}`` of the ``KEY:value;S`` lines of a VV/PP/II body. With ``check``, a line
    whose sum fails every accepted coverage raises :class:`ChecksumError`; without, it is kept
    (VV replies of some URG-04LX carry a wrong sum on SERI). Lines without ``:`` and ``;S``
    are a :class:`ProtocolError` with ``check``, skipped without. Unknown keys are kept."""
    out: dict[str, str] = {}
    for line in lines:
        key, colon, _ = line.partition(b":")
        if not colon or len(line) < 3 or line[-2:-1] != b";":
            if check:
                raise ProtocolError(f"SCIP info line {line[:60]!r} is not KEY:value;sum")
            continue
        if check and not _info_sum_ok(line):
            raise ChecksumError(f"SCIP info line {line[:60]!r}: bad checksum")
        out[key.decode("ascii", "replace")] = line[len(key) + 1 : -2].decode("ascii", "replace")
    return out


@dataclass(frozen=True)
class ScanReply:
    """A decoded scan reply. ``ranges`` (and ``intensities`` for GE/ME) hold the raw values,
    one per cluster from ``start`` to ``end`` step (values below DMIN are error codes);
    ``timestamp`` is the sensor's 24-bit millisecond counter at step 0; ``remaining`` the
    M-type frame's count field (None for G-type)."""

    echo: bytes
    command: str
    status: str
    timestamp: int
    start: int
    end: int
    cluster: int
    remaining: int | None
    ranges: npt.NDArray[np.uint32]
    intensities: npt.NDArray[np.uint32] | None
    tag: str | None = None


def scan_header(
    block: bytes | bytearray | memoryview, check: bool = True
) -> tuple[Reply, ScanEcho, int]:
    """The reply, echo fields and timestamp of a scan reply, checked: status ``00`` for G-type,
    ``99`` for an M-type frame (an M-type ``00`` is the acknowledgement, which carries no scan:
    :class:`ProtocolError`), any other status :class:`ScipStatusError`."""
    reply = parse_reply(block, check)
    echo = parse_scan_echo(reply.echo)
    want = "99" if echo.command[0] == "M" else "00"
    if reply.status != want:
        if reply.status == "00":
            raise ProtocolError(f"SCIP {echo.command} acknowledgement, not a scan frame")
        raise ScipStatusError(echo.command, reply.status)
    if not reply.body:
        raise FramingError(f"SCIP {echo.command} reply without a timestamp: truncated block")
    ts_line = reply.body[0]
    if len(ts_line) != 5:
        raise FramingError(f"SCIP timestamp line {ts_line!r}: expected 4 chars and a sum")
    ts = decode_value(check_line(ts_line, "timestamp") if check else ts_line[:4])
    return reply, echo, ts


def decode_scan(block: bytes | bytearray | memoryview, check: bool = True) -> ScanReply:
    """Decode a whole scan reply (pure Python; :func:`robocli.protocols.scip2.fast.decode_scan`
    is the C version, same results and same errors). ``check=False`` skips the data-line sums
    (the status and timestamp sums too), as urg_library does by default."""
    import numpy as np

    reply, echo, ts = scan_header(block, check)
    payload = join_data_lines(reply.body[1:], check)
    per_step = 2 if echo.intensity else 1
    want = echo.count * per_step * echo.width
    if len(payload) != want:
        raise FramingError(
            f"SCIP {echo.command} scan: {len(payload)} data chars, expected {want} "
            f"({echo.count} steps x {per_step} x {echo.width}): truncated block"
        )
    w = echo.width
    values = np.array(
        [decode_value(payload[i : i + w]) for i in range(0, len(payload), w)], dtype=np.uint32
    )
    ranges = values[::per_step] if per_step == 2 else values
    intensities = values[1::2] if per_step == 2 else None
    return ScanReply(
        reply.echo, echo.command, reply.status, ts, echo.start, echo.end, echo.cluster,
        echo.remaining, np.ascontiguousarray(ranges),
        None if intensities is None else np.ascontiguousarray(intensities), echo.tag,
    )  # fmt: skip


# ---------------------------------------------------------------------------- building


def build_reply(echo: bytes, status: str, body: bytes = b"") -> bytes:
    """A reply block: ``echo`` LF, the status with its sum (a 1-char status without), the
    already-framed ``body`` lines, and the empty line."""
    st = status.encode("ascii")
    status_line = st + LF if len(st) == 1 else with_sum(st)
    return echo + LF + status_line + body + LF


def build_info(items: Iterable[tuple[str, str]] | dict[str, str]) -> bytes:
    """VV/PP/II body lines ``KEY:value;S`` (the sum over ``KEY:value``)."""
    pairs = items.items() if isinstance(items, dict) else items
    out = []
    for key, value in pairs:
        content = f"{key}:{value}".encode("ascii")
        out.append(content + b";" + bytes((checksum(content),)) + LF)
    return b"".join(out)


def build_scan(
    echo: bytes,
    status: str,
    timestamp: int,
    ranges: Sequence[int] | Any,
    intensities: Sequence[int] | Any | None = None,
    width: int = 3,
) -> bytes:
    """A scan reply block (GD/MD frames and the like): echo, status, timestamp line, the data
    stream of ``ranges`` (interleaved with ``intensities`` when given) cut into 64-char
    lines, the empty line. The timestamp is taken mod 2^24 (the sensor's counter wraps)."""
    if intensities is not None:
        values: list[int] = []
        for r, i in zip(ranges, intensities, strict=True):
            values += (int(r), int(i))
    else:
        values = [int(v) for v in ranges]
    body = with_sum(encode_value(int(timestamp) & 0xFFFFFF, 4)) + data_lines(
        encode_values(values, width)
    )
    return build_reply(echo, status, body)
