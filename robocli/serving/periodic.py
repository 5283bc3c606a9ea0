"""The one periodic loop of robocli (:class:`PeriodicLoop`) and its error policy.

Every thread that works on a schedule runs on it: a simulator's physics and a hub's sensor
batches (:class:`~robocli.serving.ticker.Ticker`), an arm simulator's state stream, a
session's keep-alive and dead-man supervisor (:class:`~robocli.devices.tasks.PeriodicTask`),
a bridge's stop rules (:class:`~robocli.bridge.control.ControlGate`).

**Error policy.** A step that raises an :class:`Exception` is

1. counted (:attr:`PeriodicLoop.errors`) and logged with its traceback, at ERROR, once per
   run of consecutive failures: the next failures of the run are logged at DEBUG and the
   first success after them says at INFO how many failed, so a step failing at 100 Hz
   cannot flood the log;
2. handed to the owner's ``on_error(exc)``, from the loop's thread;
3. and the loop **goes on** (at its next deadline, or :data:`RETRY_S` later for a loop
   without a period), unless the owner stopped it in ``on_error``.

So the owner decides once, when it makes the loop, what an error means. A loop whose death
must stop the robot (a session's keep-alive or supervisor) stops in ``on_error`` and fails
closed: the session sends the robot's stop, and the robot's own watchdog stops it when no
keep-alive comes. A loop that must outlive one bad step passes no ``on_error`` and goes on:
a simulator's tick, a state stream, and a bridge's stop rules, whose end would leave the
robot moving with no rule to stop it. Two things end any loop, after the same logging: an
exception that is not an :class:`Exception` (``SystemExit``...), and an ``on_error`` that
raises (the owner could not be told: nothing goes on as if it had been).

**Overruns.** A loop on a ``period`` whose step returns None keeps the absolute deadlines
``t0 + k * period`` (no drift). A step that ends less than a period late is followed at
once; one that ends later does not make the loop run back to back to catch up: the
deadlines it missed are skipped and counted (:attr:`PeriodicLoop.skipped`), the first such
overrun of a loop logged at WARNING, the next ones at DEBUG.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

__all__ = ["JOIN_TIMEOUT_S", "RETRY_S", "PeriodicLoop"]

log = logging.getLogger("robocli.serving.periodic")

JOIN_TIMEOUT_S = 2.0  #: close() waits at most this long for the thread
RETRY_S = 0.1  #: a loop without a period runs a step that raised (or returned None) this late


class PeriodicLoop:
    """A daemon thread that runs ``step()`` whenever it is due (the policy on errors and
    overruns is the module's).

    ``step()`` returns the seconds until it is due again (0 or less: at once), or None for
    the next deadline ``t0 + k * period`` (:data:`RETRY_S` later without a ``period``). A
    loop with a ``period`` first runs one period after :meth:`start`; one without runs at
    once. :meth:`wake` makes it run now; :meth:`stop` ends it (the step running finishes
    first); :meth:`close` also joins it."""

    def __init__(
        self,
        name: str,
        step: Callable[[], float | None],
        *,
        period: float | None = None,
        on_error: Callable[[BaseException], None] | None = None,
    ) -> None:
        if period is not None and not period > 0:
            raise ValueError("period must be > 0")
        self.name, self.period = name, period
        self.runs = 0  #: steps run, failed ones included
        self.errors = 0  #: steps that raised
        self.skipped = 0  #: deadlines skipped after overruns
        self._step = step
        self._on_error = on_error
        self._failing = 0  # consecutive failures so far
        self._overran = False
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._started = False
        self._start_lock = threading.Lock()
        self.thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> None:
        """Start the thread (once; later calls, and calls after :meth:`stop`, do nothing)."""
        with self._start_lock:
            if self._started or self._stop.is_set():
                return
            self._started = True
        self.thread.start()

    def stop(self) -> None:
        """End the loop (from any thread, the loop's own included); does not wait."""
        self._stop.set()
        self._wake.set()

    def wake(self) -> None:
        """Run the step now instead of at its deadline."""
        self._wake.set()

    @property
    def stopped(self) -> bool:
        return self._stop.is_set()

    def close(self, timeout: float = JOIN_TIMEOUT_S) -> None:
        """Stop, and join the thread within ``timeout`` s (not from the loop's own thread).
        Idempotent."""
        self.stop()
        t = self.thread
        if self._started and t is not threading.current_thread():
            t.join(timeout)
            if t.is_alive():
                log.warning("%s did not stop within %.1f s", self.name, timeout)

    # ------------------------------------------------------------------ the thread

    def _run(self) -> None:
        period, stop, wake = self.period, self._stop, self._wake
        t0 = time.monotonic()
        k = 1 if period is not None else 0
        due = t0 + k * (period or 0.0)
        on_grid = period is not None  # the deadline is k's, not one the step set
        while not stop.is_set():
            delay = due - time.monotonic()
            if delay > 0:
                wake.wait(delay)
                wake.clear()
                if stop.is_set():
                    return
            elif on_grid and period is not None and -delay > period:
                self._overrun(-delay, period)
                k += int(-delay / period)
            try:
                result = self._step()
            except Exception as exc:
                result = None
                if not self._failed(exc):
                    return
            except BaseException as exc:
                self._failed(exc)
                return
            else:
                if self._failing:
                    log.info("%s: the step works again after %d failures", self.name,
                             self._failing)  # fmt: skip
                    self._failing = 0
            finally:
                self.runs += 1
            on_grid = result is None and period is not None
            if on_grid and period is not None:
                k += 1
                due = t0 + k * period
            elif result is None:
                due = time.monotonic() + RETRY_S
            else:
                due = time.monotonic() + result
                if period is not None:  # a None next time: the deadline after this one
                    k = int((due - t0) / period)

    def _overrun(self, late: float, period: float) -> None:
        missed = int(late / period)
        self.skipped += missed
        level = logging.DEBUG if self._overran else logging.WARNING
        self._overran = True
        log.log(level, "%s: a step overran by %.1f ms; %d deadlines skipped", self.name,
                late * 1e3, missed)  # fmt: skip

    def _failed(self, exc: BaseException) -> bool:
        """Count and log ``exc``, tell the owner; False when the loop must end."""
        self.errors += 1
        self._failing += 1
        level = logging.ERROR if self._failing == 1 else logging.DEBUG
        log.log(level, "%s: step failed (%d in a row)", self.name, self._failing, exc_info=exc)
        if self._on_error is not None:
            try:
                self._on_error(exc)
            except Exception:
                log.exception("%s: its owner could not be told of the failure; the loop ends",
                              self.name)  # fmt: skip
                return False
        return isinstance(exc, Exception)
