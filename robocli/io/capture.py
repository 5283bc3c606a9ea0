"""Captured byte streams: read them back frame by frame.

Formats, by suffix:

* ``.jsonl``: one JSON object per chunk, ``{"t": s, "dir": "c2s"|"s2c", "hex": "..."}``
  (the format of the recorded traces in ``shared/traces``; lines without ``hex`` are events);
* anything else: raw bytes of one direction (what a serial sniffer or ``cat`` saved).
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from robocli.core import Framer
from robocli.errors import RobocliError

#: direction names used in captures -> "tx" (host to robot) / "rx" (robot to host)
_DIRECTIONS = {"c2s": "tx", "client->server": "tx", "s2c": "rx", "server->client": "rx"}


@dataclass(frozen=True)
class CapturedFrame:
    t: float | None  #: seconds since the capture started, when the format has it
    direction: str  #: "tx" host->robot, "rx" robot->host, "?" unknown (raw files)
    frame: bytes  #: one whole frame (sync/prefix included)


def read_capture(path: str | Path, protocol: str = "arcos") -> Iterator[CapturedFrame]:
    """Frames of a capture file in order; each direction is framed separately, so garbage in
    one direction never hides the other's frames."""
    path = Path(path)
    try:
        if path.suffix == ".jsonl":
            yield from _read_jsonl(path, protocol)
        else:
            framer = Framer(protocol)
            for frame in framer.feed(path.read_bytes()):
                yield CapturedFrame(None, "?", frame)
    except OSError as exc:
        raise RobocliError(f"cannot read capture {path}: {exc.strerror or exc}") from None


def _read_jsonl(path: Path, protocol: str) -> Iterator[CapturedFrame]:
    framers: dict[str, Framer] = {}
    with path.open() as lines:
        for number, line in enumerate(lines, 1):
            if not line.strip():
                continue
            try:
                record = json.loads(line)
                data = bytes.fromhex(record.get("hex", ""))
            except (ValueError, AttributeError) as exc:
                raise RobocliError(f"{path}:{number}: not a capture record ({exc})") from None
            if not data:
                continue
            direction = _DIRECTIONS.get(str(record.get("dir")), "?")
            framer = framers.setdefault(direction, Framer(protocol))
            t = record.get("t")
            for frame in framer.feed(data):
                yield CapturedFrame(float(t) if t is not None else None, direction, frame)
