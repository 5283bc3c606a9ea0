"""SCIP 2.0 wire primitives: the checksum, the 2/3/4-character encodings, lines and the
64-character data blocks, the status codes, and the typed errors of a refused command.

Part of :mod:`robocli.protocols.scip2` (import from there). Pure Python: this is the
reference the C decoder (:mod:`robocli.protocols.scip2.fast`) is checked against.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import construct as cs

from robocli.errors import ChecksumError, DeviceError, FramingError

LF = b"\n"
CR = b"\r"
BLOCK_CHARS = 64  #: data characters per data-block line (the line adds its sum and LF)
MAX_LINE = 128  #: longest line accepted (data lines are 65 chars; the sum included)
MAX_ECHO = 64  #: longest echo accepted (a request is at most 15 + 1 + 16 chars)
MAX_BLOCK = 65536  #: bytes of one reply at most (a 1081-step ME frame is ~6.7 kB)
MAX_TAG = 16  #: characters of the optional ``;string`` of a request
TAG_CHARS = frozenset(b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789 ._+@")
TIMESTAMP_WRAP = 1 << 24  #: the sensor's millisecond counter wraps here (~4 h 40 min)


# ---------------------------------------------------------------------------- checksum


def checksum(data: bytes | bytearray | memoryview) -> int:
    """The SCIP sum of ``data`` as a byte value: (sum of bytes & 0x3F) + 0x30 (``0``..``o``)."""
    return (sum(bytes(data)) & 0x3F) + 0x30


def sum_char(data: bytes | bytearray | memoryview) -> bytes:
    """The SCIP sum of ``data`` as a one-byte ``bytes``."""
    return bytes((checksum(data),))


def with_sum(content: bytes) -> bytes:
    """A status/timestamp/data line: ``content`` + its sum + LF."""
    return content + sum_char(content) + LF


def strip_eol(line: bytes) -> bytes:
    """A line without its LF and a CR just before it (sensors send LF only; a stray CR from a
    converter is tolerated)."""
    if line.endswith(LF):
        line = line[:-1]
    if line.endswith(CR):
        line = line[:-1]
    return line


def check_line(line: bytes, what: str = "line") -> bytes:
    """The content of a summed line (its last char is the sum of the others); a wrong sum
    raises :class:`ChecksumError`, an empty line :class:`FramingError`."""
    if len(line) < 2:
        raise FramingError(f"SCIP {what} {line!r}: too short to carry a checksum")
    content, got = line[:-1], line[-1]
    want = checksum(content)
    if got != want:
        raise ChecksumError(f"SCIP {what} {line!r}: checksum {chr(got)!r}, expected {chr(want)!r}")
    return content


# ---------------------------------------------------------------------------- encodings


def encode_value(value: int, width: int) -> bytes:
    """``value`` in the SCIP ``width``-character encoding (6 bits per char, + 0x30, most
    significant first): 2 chars hold 0..4095, 3 chars 0..262143, 4 chars 0..16777215."""
    if width not in (2, 3, 4):
        raise ValueError(f"SCIP encodings are 2, 3 or 4 characters, not {width}")
    if not 0 <= value < 1 << (6 * width):
        raise ValueError(f"{value} does not fit {width} SCIP characters")
    return bytes(((value >> (6 * (width - 1 - i))) & 0x3F) + 0x30 for i in range(width))


def decode_value(chars: bytes | bytearray | memoryview) -> int:
    """The integer of a SCIP-encoded field; a char outside ``0``..``o`` raises
    :class:`FramingError`."""
    value = 0
    for c in bytes(chars):
        if not 0x30 <= c <= 0x6F:
            raise FramingError(f"SCIP encoded field {bytes(chars)!r}: byte 0x{c:02x} not in 0..o")
        value = (value << 6) | (c - 0x30)
    return value


def encode_values(values: Iterable[int], width: int) -> bytes:
    """A data stream (before cutting into lines): each value in ``width`` characters."""
    return b"".join(encode_value(int(v), width) for v in values)


def decode_values(payload: bytes | bytearray | memoryview, width: int) -> list[int]:
    """The values of a data stream already joined from its lines."""
    data = bytes(payload)
    if len(data) % width:
        raise FramingError(
            f"SCIP data: {len(data)} chars is not a whole number of {width}-char values"
        )
    return [decode_value(data[i : i + width]) for i in range(0, len(data), width)]


class _Encoded(cs.Adapter):  # type: ignore[misc]  # construct has no type hints
    """A ``width``-character SCIP-encoded unsigned integer."""

    def __init__(self, width: int) -> None:
        super().__init__(cs.Bytes(width))
        self.width = width

    def _decode(self, obj: bytes, context: Any, path: Any) -> int:
        return decode_value(obj)

    def _encode(self, obj: int, context: Any, path: Any) -> bytes:
        return encode_value(int(obj), self.width)


class _Summed(cs.Adapter):  # type: ignore[misc]
    """A line ``<fixed-size content><sum>LF``: parsing checks the sum, building appends it."""

    def __init__(self, subcon: Any, what: str) -> None:
        super().__init__(cs.Bytes(subcon.sizeof() + 2))
        self.inner = subcon
        self.what = what

    def _decode(self, obj: bytes, context: Any, path: Any) -> Any:
        if obj[-1:] != LF:
            raise FramingError(f"SCIP {self.what} line {obj!r} does not end in LF")
        return self.inner.parse(check_line(obj[:-1], self.what))

    def _encode(self, obj: Any, context: Any, path: Any) -> bytes:
        return with_sum(self.inner.build(obj))


Enc2 = _Encoded(2)
Enc3 = _Encoded(3)
Enc4 = _Encoded(4)

#: ``<ts4><sum>LF``: the timestamp line of a scan and the TM1 reply body
TimestampLine = _Summed(Enc4, "timestamp")
#: ``<2 status chars><sum>LF``
StatusLine = _Summed(cs.PaddedString(2, "ascii"), "status")


# ---------------------------------------------------------------------------- data blocks


def data_lines(payload: bytes) -> bytes:
    """The wire form of a data stream: 64-char lines, each with its sum and LF; the last line
    holds the remaining 1..64 chars (an empty stream has no line). Values may straddle lines."""
    return b"".join(
        with_sum(payload[i : i + BLOCK_CHARS]) for i in range(0, len(payload), BLOCK_CHARS)
    )


def join_data_lines(lines: Sequence[bytes], check: bool = True) -> bytes:
    """The data stream of a block's data lines (EOL already stripped): every line but the last
    carries exactly 64 chars, the last 1..64; each sum is checked unless ``check`` is False.

    A short or long line is a :class:`FramingError` (a truncated or garbled block); a wrong sum
    a :class:`ChecksumError`.
    """
    parts = []
    last = len(lines) - 1
    for i, line in enumerate(lines):
        n = len(line) - 1
        if n < 1 or n > BLOCK_CHARS or (i < last and n != BLOCK_CHARS):
            raise FramingError(
                f"SCIP data line {i + 1} of {len(lines)} has {max(n, 0)} chars "
                f"(expected {BLOCK_CHARS}, the last 1..{BLOCK_CHARS}): truncated block"
            )
        parts.append(check_line(line, "data line") if check else line[:-1])
    return b"".join(parts)


# ---------------------------------------------------------------------------- statuses

#: Meanings of the status codes as the specification gives them (SPEC p.11-23, UST/UTM tables of HL
#: and US). Per-command meanings of 01..07 are in :data:`COMMAND_STATUS`.
STATUS_TEXT: dict[str, str] = {
    "00": "ok",
    "99": "scan data (continuous measurement)",
    "0A": "cannot build the reply",
    "0B": "buffer shortage or command repeated",
    "0C": "command too short / too few parameters",
    "0D": "command too long / undefined command",
    "0E": "command not defined",
    "0F": "command not supported / too few parameters",
    "0G": "string (;tag) longer than 16 characters",
    "0H": "invalid character in the string (;tag)",
    "0I": "sensor in firmware-update mode",
    "0L": "sensor in an abnormal state",
    "0M": "measurement unstable",
    "10": "denied: laser off or not allowed in this state",
    "98": "measurement resumed after an error",
}

_SCAN_STATUS = {
    "01": "start step not a number",
    "02": "end step not a number",
    "03": "cluster count not a number",
    "04": "end step out of range",
    "05": "end step below the start step",
}
_MD_STATUS = {**_SCAN_STATUS, "06": "scan interval not a number", "07": "scan count not a number"}

#: command -> {status -> meaning} for the command-specific codes (SPEC p.10-18)
COMMAND_STATUS: dict[str, dict[str, str]] = {
    "BM": {"01": "laser malfunction", "02": "laser already on"},
    "TM": {
        "01": "invalid control code",
        "02": "already in time-adjust mode",
        "03": "already out of time-adjust mode",
        "04": "TM1 outside time-adjust mode",
    },
    "CR": {
        "01": "invalid speed",
        "02": "speed out of range",
        "03": "already at that speed",
        "04": "not supported",
    },
    "HS": {"01": "parameter error", "02": "already in that mode", "03": "not supported"},
    "RB": {"01": "reboot armed: send RB again within 1 s"},
    "SS": {"01": "invalid bit rate", "02": "bit rate out of range", "03": "already at that rate"},
    **{c: _SCAN_STATUS for c in ("GD", "GS", "GE", "HD", "HE")},
    **{c: _MD_STATUS for c in ("MD", "MS", "ME", "ND", "NE")},
}

#: statuses that mean success per command (anything else is an error); UL treats a second
#: BM (``02``, already on) as success, and RB's first ``01`` as the expected arming reply.
SUCCESS: dict[str, frozenset[str]] = {
    "BM": frozenset({"00", "02"}),
    "RB": frozenset({"00", "01"}),
}


def status_text(command: str, status: str) -> str:
    """What ``status`` means in a reply to ``command`` (two-letter symbol)."""
    specific = COMMAND_STATUS.get(command[:2], {})
    if status in specific:
        return specific[status]
    if status in STATUS_TEXT:
        return STATUS_TEXT[status]
    if command[:1] in "GMHN" and status.isdigit():
        n = int(status)
        if 21 <= n <= 49:
            return "processing stopped"
        if 50 <= n <= 98:
            return "hardware trouble"
    return "unknown status"


class ScipStatusError(DeviceError):
    """The sensor refused or failed a command: ``status`` is its two-character code (``"0E"``,
    ``"10"``...), ``command`` the request's symbol. ``code`` is the status as a decimal
    number when it is one (``10``), else None."""

    def __init__(self, command: str, status: str) -> None:
        self.command = command
        self.status = status
        super().__init__(
            f"SCIP {command or '?'}: status {status} ({status_text(command, status)})",
            int(status) if status.isdigit() else None,
        )


def is_success(command: str, status: str) -> bool:
    """Whether ``status`` is a success for ``command`` (M-type frames: ``99``)."""
    return status in SUCCESS.get(command[:2], frozenset({"00"}))
