"""The bookkeeping every recording sink shares (the MCAP recorder, the live view, the ROS 2
topics): :class:`SinkBase`. Below ``io`` and ``ros2`` both, so that either can build on it."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any

from robocli.closing import Closing

__all__ = ["SinkBase"]

log = logging.getLogger("robocli.sink")


class SinkBase(Closing):
    """The bookkeeping every :class:`Sink` shares: log times on an epoch fixed at the start
    (they never jump with the clock), unique link names, and the listeners to detach when
    it closes (:meth:`_detach_all`)."""

    links: dict[str, Any]

    def __init__(self) -> None:
        self._epoch_ns = time.time_ns() - time.monotonic_ns()
        self._names: set[str] = set()
        self._detach: list[Callable[[], None]] = []
        self._closed = False

    def log_ns(self, t_monotonic: float) -> int:
        """A monotonic time (s, as the devices stamp what they receive) in Unix-epoch ns."""
        return int(t_monotonic * 1e9) + self._epoch_ns

    def unique_name(self, base: str) -> str:
        """``base``, or ``base2``, ``base3``... the first not taken yet."""
        name, k = base, 1
        while name in self._names or name in self.links:
            k += 1
            name = f"{base}{k}"
        self._names.add(name)
        return name

    def on_close(self, detach: Callable[[], None]) -> None:
        """Call ``detach`` (remove a listener) when the sink closes."""
        self._detach.append(detach)

    def _close_begins(self) -> bool:
        """True once, for the first :meth:`close`: it is marked closed and detached from its
        devices (:meth:`_detach_all`); False for every later one."""
        if self._closed:
            return False
        self._closed = True
        self._detach_all()
        return True

    def _detach_all(self) -> None:
        """Call every ``detach`` given to :meth:`on_close` once (one that fails is logged)."""
        detaches, self._detach = self._detach, []
        for detach in detaches:
            try:
                detach()
            except Exception:
                log.debug("%s: detaching a listener failed", type(self).__name__, exc_info=True)
