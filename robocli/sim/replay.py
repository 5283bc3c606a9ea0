"""Recorded frames played back on their recorded spacing: the stream of a simulator that
replays a recording (``robocli sim pioneer|abb --replay FILE.mcap``).

A :class:`FrameSchedule` holds whole frames, as a device sent them, with their recorded
receive times (the MCAP log times of the recording's raw channel). :meth:`FrameSchedule.
restart` starts it (a client's session opens); :meth:`FrameSchedule.due` returns the frames
whose time has come, ``speed`` times as fast as recorded; with ``loop`` the recording starts
over after its last frame and one more typical interval.
"""

from __future__ import annotations

import bisect
import statistics
import threading
from collections.abc import Iterable
from pathlib import Path

from robocli.errors import InvalidArgument, RobocliError

__all__ = ["FrameSchedule", "recorded_frames"]


class FrameSchedule:
    """Frames at recorded times (s, any origin), replayed from :meth:`restart` on."""

    def __init__(self, frames: Iterable[tuple[float, bytes]], speed: float = 1.0,
                 loop: bool = False) -> None:  # fmt: skip
        if not (isinstance(speed, (int, float)) and 0 < speed < float("inf")):
            raise InvalidArgument(f"speed must be a positive number, not {speed!r}")
        items = sorted(frames, key=lambda f: f[0])
        if not items:
            raise InvalidArgument("nothing to replay: no frame")
        t0 = items[0][0]
        self.times = [t - t0 for t, _ in items]
        self.frames = [f for _, f in items]
        self.speed, self.loop = float(speed), loop
        gaps = [b - a for a, b in zip(self.times, self.times[1:], strict=False) if b > a]
        gap = statistics.median(gaps) if gaps else 0.1
        self.period = self.times[-1] + gap  #: recorded seconds of one lap
        self._origin: float | None = None
        self._lap = self._i = 0
        self.sent = 0  #: frames handed out since the schedule was made
        self.laps = 0  #: laps begun after the first (loop)
        self._lock = threading.Lock()

    def restart(self, now: float) -> None:
        """Play from the first frame, which is due at ``now`` (monotonic s)."""
        with self._lock:
            self._origin, self._lap, self._i = now, 0, 0

    def stop(self) -> None:
        """Nothing is due until the next :meth:`restart`."""
        with self._lock:
            self._origin = None

    @property
    def finished(self) -> bool:
        """Every frame was handed out and the schedule does not loop."""
        return not self.loop and self._i >= len(self.frames)

    def due(self, now: float) -> list[bytes]:
        """The frames due at ``now`` (monotonic s) not handed out yet, in order."""
        with self._lock:
            if self._origin is None:
                return []
            elapsed = (now - self._origin) * self.speed
            out: list[bytes] = []
            n = len(self.frames)
            while True:
                base = self._lap * self.period
                end = bisect.bisect_right(self.times, elapsed - base)
                if end > self._i:
                    out.extend(self.frames[self._i : end])
                    self._i = end
                if self._i < n or not self.loop or elapsed < base + self.period:
                    break
                self._lap, self._i = self._lap + 1, 0
                self.laps += 1
            self.sent += len(out)
            return out


def recorded_frames(path: str | Path, protocol: str, direction: str
                    ) -> list[tuple[float, bytes]]:  # fmt: skip
    """``(t, frame)`` of the first ``protocol`` link's raw frames going ``direction``
    (``rx``, or ``rx:state`` for an arm's state port) in the recording at ``path``, ``t`` in
    seconds since the recording's first message."""
    from robocli.io.record import raw_frames

    frames = [(t, frame) for t, way, frame in raw_frames(path, protocol) if way == direction]
    if not frames:
        raise RobocliError(f"{path}: no {direction} frame of the {protocol} link to replay")
    return frames
