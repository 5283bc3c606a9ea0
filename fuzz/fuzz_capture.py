"""Fuzz harness of the capture readers (:func:`robocli.io.capture.read_capture`).

The input, after its option byte, is written as a capture file (``.jsonl`` or raw bytes, by
the option byte, which also picks the framer: ARCOS, Simple Message either byte order,
ros4mat) and read back frame by frame. Reading must end or raise a
:class:`robocli.errors.RobocliError`; every byte read is accounted for, and every frame is
a whole frame of its protocol. Anything else is a finding.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import fuzz_framers
from harness import scratch

from robocli.errors import RobocliError
from robocli.io.capture import CaptureStats, read_capture

PROTOCOLS = ("arcos", "sm-le", "sm-be", "ros4mat")
_OPT_JSONL = 0x04


def _path(suffix: str) -> Path:
    return scratch("capture") / f"capture{suffix}"


def fuzz_capture(data: bytes) -> None:
    """Option byte (protocol, format), then the capture file's bytes."""
    if not data:
        return
    opt, content = data[0], data[1:]
    protocol = PROTOCOLS[opt & 3]
    path = _path(".jsonl" if opt & _OPT_JSONL else ".bin")
    path.write_bytes(content)
    stats = CaptureStats()
    frames = 0
    try:
        for captured in read_capture(path, protocol, stats):
            frames += 1
            assert captured.direction in ("tx", "rx", "?"), captured.direction
            fuzz_framers.check_frame(protocol, captured.frame)
    except RobocliError:
        return
    assert stats.bytes_read == len(content), (stats.bytes_read, len(content))
    assert stats.frames == frames, (stats.frames, frames)
    assert stats.dropped_bytes >= 0, stats.dropped_bytes


def seed_inputs(frames_by_kind: dict[str, list[bytes]]) -> list[bytes]:
    """The golden frames of each protocol as raw captures (also behind garbage) and as
    ``.jsonl`` captures (each frame split over two lines, both directions; also with lines
    that are not records)."""
    out = []
    for index, protocol in enumerate(PROTOCOLS):
        frames = frames_by_kind.get(protocol, [])
        if not frames:
            continue
        out.append(bytes((index,)) + b"".join(frames))
        out.append(bytes((index,)) + b"\x00\xfa\xff" + b"".join(frames[::-1]))
        lines = []
        for i, frame in enumerate(frames):
            direction = "c2s" if i % 2 else "s2c"
            half = len(frame) // 2
            for t, part in ((0.001 * i, frame[:half]), (0.001 * i + 0.0005, frame[half:])):
                lines.append(json.dumps({"t": t, "dir": direction, "hex": part.hex()}))
        lines.append(json.dumps({"t": 1.0, "event": "end"}))
        out.append(bytes((index | _OPT_JSONL,)) + "\n".join(lines).encode() + b"\n")
        broken = [*lines[:2], "not json", '{"hex": "zz"}', "[1, 2]", *lines[2:]]
        out.append(bytes((index | _OPT_JSONL,)) + "\n".join(broken).encode())
    return out


TARGETS: dict[str, tuple[Callable[[bytes], None], tuple[str, ...]]] = {
    "capture-readers": (fuzz_capture, PROTOCOLS),
}
