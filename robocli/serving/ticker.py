"""A periodic clock thread for the built-in simulators and the hub: physics, SIPs, state
streams and sensor sources tick on absolute deadlines ``t0 + k * period``."""

from __future__ import annotations

import time
from collections.abc import Callable

from robocli.serving.periodic import JOIN_TIMEOUT_S, PeriodicLoop

__all__ = ["JOIN_TIMEOUT_S", "Ticker"]


class Ticker(PeriodicLoop):
    """Calls ``tick(now)`` every ``period`` wall seconds, on absolute deadlines
    ``t0 + k * period`` (no drift): a :class:`~robocli.serving.periodic.PeriodicLoop` with
    its policy. When more than a period late it skips the missed ticks and counts them in
    :attr:`skipped`. An exception in ``tick`` is logged with its traceback and counted in
    :attr:`errors`; the ticker goes on (one bad tick must not stop a robot's stream).
    """

    def __init__(self, period: float, tick: Callable[[float], None], name: str) -> None:
        self._tick = tick
        super().__init__(name, self._step, period=period)

    @property
    def ticks(self) -> int:
        """Ticks run, failed ones included."""
        return self.runs

    def _step(self) -> None:
        self._tick(time.monotonic())
