"""The sensor's clock mapped to the host's (:class:`SensorClock`).

A Hokuyo stamps each scan with a 24-bit millisecond counter that wraps every 2^24 ms
(about 4 h 40 min) and restarts at 0 on RS/RT/reboot. :meth:`SensorClock.unwrap` counts the
wraps (a value more than half a period below the last one is past a wrap; a reset shows as
a jump back of less than that and is taken as a new origin, the host offset re-estimated).

The offset (host epoch seconds minus sensor seconds) is first measured as urg_node does:
TM0, then for each sample the host time before and after TM1, offset = midpoint - sensor
time; the median of the samples (:meth:`SensorClock.calibrate`). While scans stream it is
kept updated: each frame gives ``reception - stamp`` = offset + latency, latency >= its
minimum; the minimum over a sliding window of :data:`WINDOW` frames, less the latency (the
smallest delay of the first :data:`LATENCY_FRAMES` frames after the last calibration),
tracks the offset as the two clocks drift (:meth:`SensorClock.observe`).
"""

from __future__ import annotations

import statistics
import threading
from collections import deque
from collections.abc import Sequence

__all__ = ["WRAP_MS", "SensorClock"]

WRAP_MS = 1 << 24
WINDOW = 64  #: frames over which the minimum delay is taken
#: frames after a calibration whose fastest gives the latency (one late frame on a loaded
#: machine must not set it)
LATENCY_FRAMES = 8


class SensorClock:
    """Unwraps the sensor's stamps and maps them to host epoch seconds. Thread-safe."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._last: int | None = None
        self._wraps = 0
        self.offset: float | None = None
        """Host epoch seconds at sensor time 0 (unwrapped), or None before any estimate."""
        self.calibrated_offset: float | None = None  #: the last TM estimate
        self.spread = 0.0  #: half the round trip of the TM sample taken (s), its accuracy
        self.wraps = 0  #: wraps counted
        self.resets = 0  #: jumps back taken as a sensor timer reset
        self._delays: deque[float] = deque(maxlen=WINDOW)
        self._latency: float | None = None

    def unwrap(self, stamp: int) -> int:
        """The unwrapped millisecond time of a 24-bit ``stamp``."""
        stamp &= WRAP_MS - 1
        with self._lock:
            if self._last is not None:
                last = self._last & (WRAP_MS - 1)
                if stamp < last - WRAP_MS // 2:
                    self._wraps += 1
                    self.wraps += 1
                elif stamp < last - 1000:  # more than a second back: the timer was reset
                    self.resets += 1
                    self._wraps = 0
                    self._delays.clear()
                    self.offset = None
            value = stamp + self._wraps * WRAP_MS
            self._last = value
            return value

    def calibrate(self, samples: Sequence[tuple[float, int, float]]) -> float:
        """Set the offset from TM1 samples ``(host before, sensor ms, host after)`` (host
        epoch seconds); the median of ``midpoint - sensor``. Returns it."""
        if not samples:
            raise ValueError("no clock samples")
        with self._lock:
            self._last = None
            self._wraps = 0
        offsets, spreads = [], []
        for before, stamp, after in samples:
            ms = self.unwrap(stamp)
            offsets.append((before + after) / 2.0 - ms / 1000.0)
            spreads.append((after - before) / 2.0)
        offset = statistics.median(offsets)
        with self._lock:
            self.offset = self.calibrated_offset = offset
            self.spread = statistics.median(spreads)
            self._delays.clear()
            self._latency = None
        return offset

    def observe(self, ms: int, received: float) -> None:
        """A scan stamped ``ms`` (unwrapped) arrived at host epoch ``received``."""
        delay = received - ms / 1000.0
        with self._lock:
            self._delays.append(delay)
            if self.offset is None:  # no calibration: the fastest frame is the best guess
                self.offset = min(self._delays)
                self._latency = 0.0
            elif self._latency is None:
                if len(self._delays) >= LATENCY_FRAMES:  # the fastest of the first frames
                    self._latency = max(0.0, min(self._delays) - self.offset)
            elif len(self._delays) == self._delays.maxlen:
                self.offset = min(self._delays) - self._latency

    def to_host(self, ms: int) -> float | None:
        """Host epoch seconds of unwrapped sensor time ``ms`` (None before any estimate)."""
        off = self.offset
        return None if off is None else off + ms / 1000.0
