"""Periodic tasks of a :class:`~robocli.devices.session.Session` (:class:`PeriodicTask`):
keep-alives, supervisors, dead-man checks, each a thread that sleeps until it is due."""

from __future__ import annotations

import threading
from collections.abc import Callable


class PeriodicTask:
    """A thread that runs ``step()`` whenever it is due, sleeping on an event in between.

    ``step`` does its work and returns the seconds until it wants to run again (its next
    deadline, e.g. "0.4 s after the last packet sent"). :meth:`stop` wakes the thread at once;
    :meth:`wake` makes it run ``step`` now. An exception from ``step`` ends the task and goes
    to ``on_error`` (the session fails closed); it never disappears silently.
    """

    def __init__(
        self,
        name: str,
        step: Callable[[], float],
        on_error: Callable[[BaseException], None],
    ) -> None:
        self.name = name
        self._step = step
        self._on_error = on_error
        self._stop = threading.Event()
        self._wake = threading.Event()
        self.thread = threading.Thread(target=self._run, name=name, daemon=True)

    def start(self) -> None:
        self.thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._wake.set()

    def wake(self) -> None:
        self._wake.set()

    @property
    def stopped(self) -> bool:
        return self._stop.is_set()

    def _run(self) -> None:
        delay = 0.0
        while not self._stop.is_set():
            if delay > 0:
                self._wake.wait(delay)
                self._wake.clear()
                if self._stop.is_set():
                    return
            try:
                delay = self._step()
            except BaseException as exc:
                if not self._stop.is_set():
                    self._on_error(exc)
                return


__all__ = ["PeriodicTask"]
