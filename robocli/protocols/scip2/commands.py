"""SCIP 2.0 requests: each command's fixed-width decimal parameters declared once with
``construct``, built by :func:`build_request` and parsed (with the sensor's error statuses
for malformed requests) by :func:`parse_request`.

Part of :mod:`robocli.protocols.scip2` (import from there).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Any

import construct as cs

from robocli.errors import InvalidArgument, ProtocolError
from robocli.protocols.common import DECODE_ERRORS
from robocli.protocols.scip2.wire import LF, MAX_TAG, TAG_CHARS, strip_eol

SCIP20 = b"SCIP2.0"  #: the SCIP 1.1 line that switches the sensor to SCIP 2.0


class _Digits(cs.Adapter):  # type: ignore[misc]  # construct has no type hints
    """A fixed-width decimal ASCII field (``0044``)."""

    def __init__(self, width: int) -> None:
        super().__init__(cs.Bytes(width))
        self.width = width

    def _decode(self, obj: bytes, context: Any, path: Any) -> int:
        if not obj.isdigit():
            raise cs.ValidationError(f"{obj!r} is not {self.width} decimal digits", path=path)
        return int(obj)

    def _encode(self, obj: int, context: Any, path: Any) -> bytes:
        value = int(obj)
        if not 0 <= value < 10**self.width:
            raise cs.ValidationError(f"{value} does not fit {self.width} digits", path=path)
        return b"%0*d" % (self.width, value)


_SCAN = cs.Struct("start" / _Digits(4), "end" / _Digits(4), "cluster" / _Digits(2))
_STREAM = cs.Struct(
    "start" / _Digits(4),
    "end" / _Digits(4),
    "cluster" / _Digits(2),
    "interval" / _Digits(1),
    "count" / _Digits(2),
)
_NONE = cs.Struct()

#: command symbol -> declaration of its parameters (after the symbol, before ``;tag``). The
#: 3-character symbols that start with ``%`` are the state commands of the UST / UTM-30LX-EW
#: firmware (hokuyolx): ``%ST`` asks the sensor's state, ``%SL`` puts it to sleep.
PARAMS: dict[str, Any] = {
    **{c: _NONE for c in ("VV", "PP", "II", "BM", "QT", "RS", "RT", "RB", "%ST", "%SL")},
    "TM": cs.Struct("code" / _Digits(1)),
    "SS": cs.Struct("bitrate" / _Digits(6)),
    "CR": cs.Struct("speed" / _Digits(2)),
    "HS": cs.Struct("mode" / _Digits(1)),
    **{c: _SCAN for c in ("GD", "GS", "GE", "HD", "HE")},
    **{c: _STREAM for c in ("MD", "MS", "ME", "ND", "NE")},
}

#: status a sensor gives for a non-numeric parameter, per field (SPEC p.10-18)
_FIELD_STATUS = {"start": "01", "end": "02", "cluster": "03", "interval": "06", "count": "07"}

SCAN_COMMANDS = frozenset(("GD", "GS", "GE", "MD", "MS", "ME"))  #: decoded by decode_scan


def _check_tag(tag: str) -> bytes:
    raw = tag.encode("ascii", "replace")
    if len(raw) > MAX_TAG or not set(raw) <= TAG_CHARS:
        raise InvalidArgument(
            f"SCIP tag {tag!r}: at most {MAX_TAG} letters, digits, space or . _ + @"
        )
    return raw


def build_request(command: str, tag: str | None = None, **params: int) -> bytes:
    """The request line of ``command`` (``"GD"``, ``"MD"``, ``"TM"``..., or ``"SCIP2.0"``)
    with its parameters, the optional ``;tag`` echoed by the sensor, and LF.

    >>> build_request("GD", start=44, end=725, cluster=1)
    b'GD0044072501\\n'
    """
    if command == SCIP20.decode():
        if params or tag:
            raise InvalidArgument("SCIP2.0 takes no parameters")
        return SCIP20 + LF
    decl = PARAMS.get(command)
    if decl is None:
        raise InvalidArgument(f"unknown SCIP command {command!r}")
    if decl is _STREAM:
        params = {"interval": 0, "count": 0, **params}
    if decl is _SCAN or decl is _STREAM:
        params = {"cluster": 1, **params}
    names = {sub.name for sub in decl.subcons}
    if set(params) != names:
        raise InvalidArgument(f"SCIP {command} takes {sorted(names)}, got {sorted(params)}")
    try:
        body = bytes(decl.build(params))
    except cs.ConstructError as exc:
        raise InvalidArgument(f"SCIP {command}: {str(exc).splitlines()[0]}") from None
    suffix = b";" + _check_tag(tag) if tag is not None else b""
    return command.encode() + body + suffix + LF


@dataclass(frozen=True)
class Request:
    """A parsed request line. ``error`` is the status the sensor answers a malformed request
    with (``"0C"`` too short, ``"0D"`` too long, ``"0E"`` unknown, ``"0G"``/``"0H"`` bad tag,
    ``"01"``.. a non-numeric field), else None. ``echo`` is the line as the sensor echoes it."""

    command: str
    params: dict[str, int] = field(default_factory=dict)
    tag: str | None = None
    error: str | None = None
    echo: bytes = b""


def parse_request(line: bytes) -> Request:
    """Parse one request line (terminator LF, CR or CR LF, or none) as the sensor does."""
    echo = strip_eol(line).rstrip(b"\r")
    if echo == SCIP20:
        return Request("SCIP2.0", echo=echo)
    text, sep, tag_raw = echo.partition(b";")
    tag = tag_raw.decode("ascii", "replace") if sep else None
    command = text[: 3 if text[:1] == b"%" else 2].decode("ascii", "replace")
    decl = PARAMS.get(command)
    if decl is None:
        return Request(command, tag=tag, error="0E", echo=echo)
    if sep and len(tag_raw) > MAX_TAG:
        return Request(command, tag=tag, error="0G", echo=echo)
    if sep and not set(tag_raw) <= TAG_CHARS:
        return Request(command, tag=tag, error="0H", echo=echo)
    body = text[len(command) :]
    size = decl.sizeof()
    if len(body) != size:
        return Request(command, tag=tag, error="0C" if len(body) < size else "0D", echo=echo)
    params: dict[str, int] = {}
    offset = 0
    for sub in decl.subcons:
        width = sub.sizeof()
        chunk = body[offset : offset + width]
        offset += width
        try:
            params[sub.name] = sub.parse(chunk)
        except DECODE_ERRORS:
            return Request(command, params, tag, _FIELD_STATUS.get(sub.name, "01"), echo)
    return Request(command, params, tag, None, echo)


@dataclass(frozen=True)
class ScanEcho:
    """The echo of a scan command (GD/GS/GE or an MD/MS/ME frame or acknowledgement):
    ``remaining`` is the count field of an M-type echo (in frames: scans still to come)."""

    command: str
    start: int
    end: int
    cluster: int
    interval: int | None = None
    remaining: int | None = None
    tag: str | None = None

    @property
    def count(self) -> int:
        """Values per quantity the reply carries: ceil((end - start + 1) / cluster)."""
        c = max(self.cluster, 1)
        return (self.end - self.start + c) // c if self.end >= self.start else 0

    @property
    def width(self) -> int:
        """Characters per value: 2 for GS/MS, 3 for GD/MD/GE/ME."""
        return 2 if self.command[1] == "S" else 3

    @property
    def intensity(self) -> bool:
        """Whether each step carries range then intensity (GE/ME)."""
        return self.command[1] == "E"


def parse_scan_echo(echo: bytes | bytearray | memoryview) -> ScanEcho:
    """The fields of a scan reply's echo line; anything else is a :class:`ProtocolError`.
    Cached: a stream repeats the same few echoes every frame."""
    return _parse_scan_echo(bytes(echo))


@functools.lru_cache(maxsize=256)
def _parse_scan_echo(echo: bytes) -> ScanEcho:
    req = parse_request(echo)
    if req.command not in SCAN_COMMANDS or req.error is not None:
        raise ProtocolError(f"SCIP echo {echo[:40]!r} is not a scan command")
    p = req.params
    if p["end"] < p["start"]:
        raise ProtocolError(f"SCIP echo {echo[:40]!r}: end step below the start step")
    return ScanEcho(
        req.command, p["start"], p["end"], p["cluster"], p.get("interval"), p.get("count"), req.tag
    )
