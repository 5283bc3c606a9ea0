"""Every SCIP line, named and decoded, for a protocol analyser (``robocli dump laser``):
:func:`describe_request` for a request line, :func:`describe_reply` for a reply block (each
line with what it is: echo, status and its meaning, ``KEY:value`` with its sum checked,
timestamp, data lines, and a summary of the decoded scan). Never raises on bad input: what
does not decode is said so."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, Any

from robocli.analysis.packets import Line, Packet
from robocli.errors import RobocliError
from robocli.protocols import scip2

__all__ = ["Line", "ScipCapture", "decode_packet", "describe_reply", "describe_request"]

MAX_CAPTURE_LINE = 1 << 20  #: longest .jsonl line read
MAX_GAP = 16 << 20  #: bytes read without a block before giving up (as robocli.io.capture)


def _text(raw: bytes) -> str:
    return raw.decode("ascii", "backslashreplace")


def describe_request(line: bytes) -> Line:
    """A request line (terminator stripped or not)."""
    raw = line.rstrip(b"\r\n")
    req = scip2.parse_request(raw)
    if req.error is not None:
        what = f"{req.command}: malformed (the sensor answers {req.error})"
    elif req.command == "SCIP2.0":
        what = "switch to SCIP 2.0"
    else:
        params = " ".join(f"{k} {v}" for k, v in req.params.items())
        what = f"{req.command} {params}".rstrip() + (f"  tag {req.tag!r}" if req.tag else "")
    return Line(_text(raw), what)


def _sum_ok(line: bytes) -> str:
    return "sum ok" if len(line) > 1 and line[-1] == scip2.checksum(line[:-1]) else "BAD SUM"


def describe_reply(block: bytes) -> list[Line]:
    """The lines of one reply block, each named and decoded, then a summary line."""
    lines = block.split(b"\n")
    while lines and lines[-1] == b"":
        lines.pop()
    if not lines:
        return [Line("", "empty")]
    out = [Line(_text(lines[0]), "echo")]
    command = "SCIP2.0" if lines[0] == scip2.SCIP20 else _text(lines[0][:2])
    if len(lines) < 2:
        return out + [Line("", "no status line: truncated")]
    st = lines[1]
    code = _text(st[:2]) if len(st) == 3 else _text(st)
    meaning = scip2.status_text(command, code) if len(st) == 3 else "SCIP 1.1 / switch status"
    out.append(Line(_text(st), f"status {code}: {meaning}" +
                    (f", {_sum_ok(st)}" if len(st) == 3 else "")))  # fmt: skip
    body = lines[2:]
    scan = command[:1] in ("G", "M") and command in scip2.SCAN_COMMANDS and body
    if scan:
        stamp = body[0]
        try:
            value = scip2.decode_value(stamp[:4])
            out.append(Line(_text(stamp), f"timestamp {value} ms, {_sum_ok(stamp)}"))
        except RobocliError as exc:
            out.append(Line(_text(stamp), f"timestamp: {exc}"))
        for i, line in enumerate(body[1:]):
            out.append(Line(_text(line), f"data {i + 1}/{len(body) - 1}, {len(line) - 1} "
                                         f"chars, {_sum_ok(line)}"))  # fmt: skip
        out.append(Line("", _scan_summary(block)))
        return out
    for line in body:
        if b":" in line and line[-2:-1] == b";":
            key, _, text = line[:-2].partition(b":")
            ok = _info_ok(line)
            out.append(Line(_text(line), f"{_text(key)} = {_text(text)}, "
                                         f"{'sum ok' if ok else 'BAD SUM'}"))  # fmt: skip
        elif len(line) == 5 and command == "TM":
            out.append(Line(_text(line), f"time {scip2.decode_value(line[:4])} ms, "
                                         f"{_sum_ok(line)}"))  # fmt: skip
        else:
            out.append(Line(_text(line), "line"))
    return out


def _info_ok(line: bytes) -> bool:
    try:
        scip2.parse_info([line], check=True)
    except RobocliError:
        return False
    return True


def _scan_summary(block: bytes) -> str:
    try:
        s = scip2.decode_scan(block)
    except RobocliError as exc:
        return f"scan does not decode: {exc}"
    r = s.ranges
    what = f"= {s.command} {len(r)} values, steps {s.start}..{s.end} cluster {s.cluster}"
    if len(r):
        what += f", {int(r.min())}..{int(r.max())} (mm or codes)"
    if s.remaining is not None:
        what += f", {s.remaining} to come"
    return what


def decode_packet(direction: str, frame: bytes, t: float | None) -> Packet:
    """A request line ("tx") or a reply block ("rx"), each of its lines described in
    :attr:`Packet.lines <robocli.analysis.packets.Packet.lines>` (the name is the first's)."""
    lines = (describe_request(frame),) if direction == "tx" else tuple(describe_reply(frame))
    return Packet(t, direction, lines[0].text if lines else "", {}, frame, lines=lines)


class ScipCapture:
    """The SCIP frames of a capture, streamed in bounded memory: a ``.jsonl`` of
    ``{"t", "dir": "c2s"|"s2c", "hex"}`` chunks (``dump pioneer --output``'s format), a
    recording of ``record --laser`` (``.mcap``: its raw ``scip2`` channels) or raw bytes the
    sensor sent. Iterate it for ``(t, direction, frame)``; :attr:`start_unix` is the Unix
    time of ``t`` 0 once the file said it, :attr:`frames` and :attr:`dropped_bytes` count
    what the reading found. A ``.jsonl`` line longer than :data:`MAX_CAPTURE_LINE` is
    skipped; :data:`MAX_GAP` bytes without a block raise :class:`RobocliError`."""

    def __init__(self, path: str | Path, on_start: Callable[[float], None] | None = None) -> None:
        self.path = Path(path)
        self.on_start = on_start  #: told the Unix time of ``t`` 0 when the file says it
        self.frames = 0
        self.dropped_bytes = 0

    def __iter__(self) -> Iterator[tuple[float, str, bytes]]:
        if self.path.suffix == ".mcap":
            yield from self._recording()
            return
        from robocli.protocols.scip2 import fast
        from robocli.protocols.scip2.framing import RequestFramer

        rx, tx = fast.reply_framer(), RequestFramer()
        gap = 0
        try:
            with self.path.open("rb") as stream:
                for t, direction, data, size in self._chunks(stream):
                    framer: Any = tx if direction == "tx" else rx
                    frames = framer.feed(data)
                    for frame in frames:
                        self.frames += 1
                        yield t, direction, frame
                    gap = 0 if frames else gap + size
                    if gap > MAX_GAP:
                        raise RobocliError(f"{self.path}: {MAX_GAP >> 20} MiB without a SCIP "
                                           "block; not a capture")  # fmt: skip
        finally:
            self.dropped_bytes = rx.stats.dropped_bytes + tx.stats.dropped_bytes

    def _recording(self) -> Iterator[tuple[float, str, bytes]]:
        from robocli.io.capture import CaptureStats
        from robocli.io.record import info, raw_frames

        stats = CaptureStats()
        self._started(info(self.path).start_ns / 1e9)  # raw_frames: s since the first message
        try:
            yield from raw_frames(self.path, "scip2", stats)
        finally:
            self.frames, self.dropped_bytes = stats.frames, stats.dropped_bytes

    def _started(self, unix_time: float) -> None:
        if self.on_start is not None:
            self.on_start(unix_time)

    def _chunks(self, stream: IO[bytes]) -> Iterator[tuple[float, str, bytes, int]]:
        """``(t, direction, bytes, bytes read)``: raw bytes (the sensor's side), or the
        records of a ``.jsonl`` capture (a line that is no record gives no bytes)."""
        if self.path.suffix != ".jsonl":
            while data := stream.read(65536):
                yield 0.0, "rx", data, len(data)
            return
        while raw := stream.readline(MAX_CAPTURE_LINE + 1):
            size = len(raw)
            if not raw.endswith(b"\n") and size > MAX_CAPTURE_LINE:  # too long: skip to its end
                while (more := stream.readline(MAX_CAPTURE_LINE + 1)) and not more.endswith(b"\n"):
                    size += len(more)
                size += len(more)
                raw = b""
            rec = _record(raw) if raw else None
            if rec is not None and rec[1] == "start":  # {"event": "start", "unix_time": ...}
                self._started(rec[0])
                rec = None
            yield (*rec, size) if rec is not None else (0.0, "rx", b"", size)


def _record(raw: bytes) -> tuple[float, str, bytes] | None:
    try:
        obj = json.loads(raw)
        if obj.get("event") == "start":
            return float(obj["unix_time"]), "start", b""
        data = bytes.fromhex(obj["hex"])
        direction = {"c2s": "tx", "s2c": "rx"}[obj["dir"]]
        return float(obj.get("t", 0.0)), direction, data
    except (ValueError, KeyError, TypeError, AttributeError):
        return None
