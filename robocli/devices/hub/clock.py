"""The hub's clock as seen from the client: the offset estimate and the mapping of the hub's
sample times onto the client's clock.

Every data reply carries the hub's send time; each pull gives one NTP-style sample
``offset = packet_timestamp - (t_request + t_reply) / 2`` whose error is at most half the
round trip. The estimate is the sample with the smallest round trip among the last
:data:`CLOCK_WINDOW` pulls (a min-RTT filter), and ``Reading.t`` is on the client's clock
(``hub_t - offset``) unless ``hub_clock=True``. The offset applied follows the estimate by
slewing (:data:`CLOCK_SLEW`), so that sample times never step back between reads.

Part of the hub client (:mod:`robocli.devices.hub.client`, which re-exports these names).
"""

from __future__ import annotations

import math
import threading
from collections import deque
from typing import Any

import numpy as np

__all__ = ["CLOCK_SLEW", "CLOCK_STEP", "CLOCK_WINDOW", "ClockSync"]

#: Pulls whose round trips the clock filter looks at.
CLOCK_WINDOW = 64
#: How fast sample times follow a new clock-offset estimate: at most this many seconds per
#: second of hub time (1 %), so that they never step back between reads (see
#: :meth:`Hub.read <robocli.devices.hub.client.Hub.read>`).
CLOCK_SLEW = 0.01
#: A new estimate that puts sample times later by more than this is stepped to at once
#: (times only jump forward); smaller ones, and every one that puts them earlier, are slewed.
CLOCK_STEP = 0.128


class ClockSync:
    """NTP-style offset of the hub's clock from the client's (min-RTT filter), and the
    mapping of hub times onto the client's clock that follows it (per sensor)."""

    def __init__(self, window: int = CLOCK_WINDOW) -> None:
        self._samples: deque[tuple[float, float]] = deque(maxlen=window)
        self._lock = threading.Lock()
        self.offset: float | None = None
        self.rtt: float | None = None
        self._mapped: dict[str, tuple[float, float]] = {}  # last sample: hub t, offset used

    def add(self, t_request: float, t_reply: float, hub_time: float) -> None:
        """One exchange: client times around it and the hub's send time in the reply."""
        if hub_time == 0.0 or not math.isfinite(hub_time):  # no send time, or a broken one
            return
        rtt = t_reply - t_request
        with self._lock:
            self._samples.append((rtt, hub_time - (t_request + t_reply) / 2))
            self.rtt, self.offset = min(self._samples)

    def client_times(self, key: str, hub_t: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
        """``hub_t`` on the client's clock, never earlier than the times already returned.

        The clock-offset estimate changes between reads (by up to a few milliseconds early
        in a session, as faster round trips come in): applied as is, a sample could get an
        earlier time than the previous read's last one. Each sensor's mapping instead starts
        from the offset applied to its last sample and moves toward the estimate by at most
        :data:`CLOCK_SLEW` seconds per second of hub time (a slew: within a reading and
        across reads, times keep their order and their spacing within 1 %). A first reading
        takes the estimate as is; an estimate that puts times later by over
        :data:`CLOCK_STEP` s is stepped to (forward only)."""
        h: np.ndarray[Any, Any] = np.asarray(hub_t, dtype=np.float64)
        target = self.offset
        if target is None:  # nothing to map with yet: the hub's times as they are
            same: np.ndarray[Any, Any] = h.copy()
            return same
        anchor = self._mapped.get(key)
        if anchor is None or anchor[1] == target or anchor[1] - target > CLOCK_STEP:
            t: np.ndarray[Any, Any] = h - target  # the common case: nothing to slew
            if len(h) and math.isfinite(h[-1]):
                self._mapped[key] = (float(h[-1]), target)
            elif len(finite := np.flatnonzero(np.isfinite(h))):
                self._mapped[key] = (float(h[finite[-1]]), target)
            return t
        h0, o0 = anchor
        with np.errstate(invalid="ignore"):  # NaN hub times map to NaN
            reach = CLOCK_SLEW * np.maximum(h - h0, 0.0)
            offsets = o0 + np.clip(target - o0, -reach, reach)
        finite = np.flatnonzero(np.isfinite(h) & np.isfinite(offsets))
        if len(finite):
            last = finite[-1]
            self._mapped[key] = (float(h[last]), float(offsets[last]))
        slewed: np.ndarray[Any, Any] = h - offsets
        return slewed
