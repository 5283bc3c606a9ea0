"""Recorded frames played back on their recorded spacing: the stream of a simulator that
replays a recording (``robocli sim pioneer|abb --replay FILE.mcap``).

A :class:`FrameSchedule` holds whole frames, as a device sent them, with their recorded
receive times (the MCAP log times of the recording's raw channel). :meth:`FrameSchedule.
restart` starts it (a client's session opens); :meth:`FrameSchedule.due` returns the frames
whose time has come, ``speed`` times as fast as recorded; with ``loop`` the recording starts
over after its last frame and one more typical interval.

A simulator takes its frames from a :class:`PacketSource`, not from a file: the simulators
know nothing of recordings, and :class:`robocli.io.record.replay.RecordedPackets` (an MCAP
recording) is the source that ``robocli sim ... --replay`` hands them.
"""

from __future__ import annotations

import bisect
import statistics
import threading
from collections.abc import Iterable, Mapping
from typing import Protocol

from robocli.errors import InvalidArgument

__all__ = ["FrameSchedule", "PacketSource"]


class PacketSource(Protocol):
    """A source of recorded packets: what a simulator replays."""

    @property
    def name(self) -> str:
        """What the packets come from (a recording's path), for messages."""
        ...  # pragma: no cover

    def frames(self, protocol: str, direction: str) -> list[tuple[float, bytes]]:
        """``(t, frame)`` of the first ``protocol`` link's whole frames going ``direction``
        (``rx``, or ``rx:state`` for an arm's state port), in order, ``t`` in seconds since
        the source's start. Raises :class:`~robocli.errors.RobocliError` when there is
        none."""
        ...  # pragma: no cover

    def link_metadata(self, protocol: str) -> Mapping[str, str]:
        """What was noted about that link when it was recorded (``byte_order``,
        ``real_size``...); empty when nothing was."""
        ...  # pragma: no cover


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
