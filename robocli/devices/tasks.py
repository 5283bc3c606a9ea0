"""Periodic tasks of a :class:`~robocli.devices.session.Session` (:class:`PeriodicTask`):
keep-alives, supervisors, dead-man checks, each a thread that sleeps until it is due."""

from __future__ import annotations

from collections.abc import Callable

from robocli.serving.periodic import PeriodicLoop


class PeriodicTask(PeriodicLoop):
    """A :class:`~robocli.serving.periodic.PeriodicLoop` of a session, with its policy:
    ``step`` does its work and returns the seconds until it wants to run again (its next
    deadline, e.g. "0.4 s after the last packet sent"); :meth:`stop` wakes the thread at
    once; :meth:`wake` makes it run ``step`` now. An exception from ``step`` is logged, ends
    the task and goes to ``on_error``, where the session fails closed (it stops the
    robot); it never disappears silently.
    """

    def __init__(
        self,
        name: str,
        step: Callable[[], float],
        on_error: Callable[[BaseException], None],
    ) -> None:
        self._fail_session = on_error
        super().__init__(name, step, on_error=self._fail_closed)

    def _fail_closed(self, exc: BaseException) -> None:
        """The task ends, and its session fails (unless it is closing already)."""
        self.stop()
        self._fail_session(exc)


__all__ = ["PeriodicTask"]
