"""A periodic clock thread for the built-in simulators and the hub: physics, SIPs, state
streams and sensor sources tick on absolute deadlines ``t0 + k * period``."""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

__all__ = ["JOIN_TIMEOUT_S", "Ticker"]

log = logging.getLogger("robocli.serving.ticker")

JOIN_TIMEOUT_S = 2.0  #: close() waits at most this long for the threads, in total


class Ticker:
    """Calls ``tick(now)`` every ``period`` wall seconds, on absolute deadlines
    ``t0 + k * period`` (no drift); when more than a period late it skips the missed ticks
    and counts them in :attr:`skipped`.

    An exception in ``tick`` is logged with its traceback and counted in :attr:`errors`; the
    ticker goes on (one bad tick must not stop a robot's stream).
    """

    def __init__(self, period: float, tick: Callable[[float], None], name: str) -> None:
        if not period > 0:
            raise ValueError("period must be > 0")
        self.period, self.name = period, name
        self.errors = 0
        self.ticks = 0
        self.skipped = 0
        self._tick = tick
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Start ticking (once; later calls do nothing)."""
        if self._thread is None and not self._stop.is_set():
            self._thread = threading.Thread(target=self._loop, name=self.name, daemon=True)
            self._thread.start()

    def close(self, timeout: float = JOIN_TIMEOUT_S) -> None:
        """Stop and join (within ``timeout`` s). Idempotent."""
        self._stop.set()
        t = self._thread
        if t is not None and t is not threading.current_thread():
            t.join(timeout)
            if t.is_alive():
                log.warning("ticker %s did not stop within %.1f s", self.name, timeout)

    def _loop(self) -> None:
        period, stop = self.period, self._stop
        t0 = time.monotonic()
        k = 0
        while not stop.is_set():
            k += 1
            delay = t0 + k * period - time.monotonic()
            if delay > 0:
                if stop.wait(delay):
                    break
            elif -delay > period:
                skipped = int(-delay / period)
                log.debug("%s %.1f ms late; skipping %d ticks", self.name, -delay * 1e3, skipped)
                k += skipped
                self.skipped += skipped
            try:
                self._tick(time.monotonic())
            except Exception:  # logged whole and counted; the stream goes on
                self.errors += 1
                log.exception("%s: tick failed", self.name)
            self.ticks += 1
