"""Listeners that cannot kill the thread that calls them (:class:`Listeners`): every frame
a :class:`~robocli.devices.session.Session` sends and receives goes to its
:data:`FrameListener` callbacks, and devices keep their own (scans, watchdog trips)."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Generic, TypeVar

if TYPE_CHECKING:
    from robocli.devices.stats import LinkStats

#: the session's logger: a listener's failure is logged where it was before the split
log = logging.getLogger("robocli.devices.session")

#: Listener signature: (direction "tx"/"rx", payload, monotonic time of send/receipt).
FrameListener = Callable[[str, bytes, float], None]

F = TypeVar("F", bound=Callable[..., Any])


class Listeners(Generic[F]):
    """Callbacks that cannot kill the thread that calls them.

    :meth:`notify` calls each listener in the order added. An exception from a listener is
    caught, counted in ``stats.listener_errors`` and logged, with its traceback the first time
    that listener fails; the listener stays registered and the next one is still called.
    """

    def __init__(self, stats: LinkStats, where: str) -> None:
        self._stats = stats
        self._where = where
        self._items: tuple[F, ...] = ()
        self._failed: set[int] = set()
        self._lock = threading.Lock()

    def add(self, listener: F) -> None:
        with self._lock:
            self._items = (*self._items, listener)

    def remove(self, listener: F) -> None:
        """Remove ``listener``; a listener that was not added is ignored."""
        with self._lock:
            self._items = tuple(x for x in self._items if x is not listener)

    def __len__(self) -> int:
        return len(self._items)

    def notify(self, *args: Any) -> None:
        for listener in self._items:
            try:
                listener(*args)
            except Exception:
                self._stats.add("listener_errors")
                if id(listener) not in self._failed:
                    self._failed.add(id(listener))
                    log.error(
                        "%s: listener %r raised; it stays registered, later failures are "
                        "only counted (stats.listener_errors)",
                        self._where,
                        listener,
                        exc_info=True,
                    )


__all__ = ["FrameListener", "Listeners"]
