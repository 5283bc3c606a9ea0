"""The counters of one link (:class:`LinkStats`), kept by a
:class:`~robocli.devices.session.Session` and extended by each device (e.g.
:class:`~robocli.devices.pioneer.link.PioneerStats`)."""

from __future__ import annotations

import threading
from collections import Counter
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from robocli.core import Framer


class LinkStats:
    """Counters of one link, safe to update from any thread and to read at any time.

    ``sent``/``received`` count packets by name; ``bad_checksums`` and ``dropped_bytes`` come
    from the framer's resynchronisation; ``decode_errors`` are frames that did not decode;
    ``listener_errors`` are exceptions raised by listeners; ``write_timeouts`` are writes
    that missed their deadline.
    """

    _COUNTERS: tuple[str, ...] = (
        "bad_checksums",
        "dropped_bytes",
        "decode_errors",
        "listener_errors",
        "write_timeouts",
    )

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.sent: Counter[str] = Counter()
        self.received: Counter[str] = Counter()
        self.decode_errors = 0
        self.listener_errors = 0
        self.write_timeouts = 0

    def add(self, name: str, n: int = 1) -> None:
        """Add ``n`` to the counter ``name`` (thread-safe)."""
        with self._lock:
            setattr(self, name, getattr(self, name) + n)

    def count_sent(self, name: str) -> None:
        with self._lock:
            self.sent[name] += 1

    def count_received(self, name: str) -> None:
        with self._lock:
            self.received[name] += 1

    #: the framer whose resynchronisation counters these are (read when asked, so that
    #: the per-frame path does not pay for them)
    framer: Framer | None = None

    @property
    def bad_checksums(self) -> int:
        return self.framer.stats.bad_checksums if self.framer is not None else 0

    @property
    def dropped_bytes(self) -> int:
        return self.framer.stats.dropped_bytes if self.framer is not None else 0

    def as_dict(self) -> dict[str, Any]:
        """A consistent, JSON-ready copy of every counter."""
        with self._lock:
            out: dict[str, Any] = {name: getattr(self, name) for name in self._counter_names()}
            out["sent"] = dict(self.sent)
            out["received"] = dict(self.received)
        return out

    def _counter_names(self) -> tuple[str, ...]:
        return self._COUNTERS

    def __repr__(self) -> str:
        data = self.as_dict()
        counts = " ".join(f"{k}={v}" for k, v in data.items() if not isinstance(v, dict))
        return (
            f"<{type(self).__name__} {counts} sent={sum(self.sent.values())} "
            f"received={sum(self.received.values())}>"
        )


__all__ = ["LinkStats"]
