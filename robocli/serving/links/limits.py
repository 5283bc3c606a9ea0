"""What every link of one server obeys and counts: its limits (:class:`LinkLimits`), the
output budget shared by the server's links (:class:`OutputBudget`) and the counters
(:class:`ServerLinkStats`).

Part of :mod:`robocli.serving.links` (import from there).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

EVICT_WAIT_S = 1.0
"""How long, at most, one charge over the budget waits in all for the output locks of the
links that should pay first (held by their own threads, which the machine may have
descheduled) before the next ones are asked without waiting."""


class OutputBudget:
    """Memory held by output waiting for its peers, summed over the links of one server.

    A link is charged the whole of the buffers its waiting output keeps alive (a reply of
    which the kernel took all but a byte still holds all of its memory) until its queue is
    empty. ``cap``: the most that may be held at once (None: no bound). A charge that would
    take the total over the cap is paid by the links that cause it: other links holding
    output are dropped first, those not :attr:`~Link.privileged` before those that are, the
    one waiting longest first (a peer that does not read), and never a privileged link for an
    unprivileged one; if that is not enough, the link charged is dropped. :attr:`peak` is the
    most ever held at once (within the cap), :attr:`evicted` the links dropped to make room.
    Thread-safe.
    """

    def __init__(self, cap: int | None = None) -> None:
        if cap is not None and cap <= 0:
            raise ValueError("the output budget must be > 0 bytes")
        self.cap = cap
        self.total = 0
        self.peak = 0
        self.overflows = 0  #: links dropped because the budget was full when they were charged
        self.evicted = 0  #: links dropped to make room for another link's output
        self._holders: dict[Any, None] = {}  # links charged now
        self._lock = threading.Lock()

    def charge(self, link: Any, n: int) -> bool:
        """Charge ``link`` ``n`` more bytes (called with ``link``'s output lock held); False
        when the total would go over the cap even after dropping the links that may be."""
        if self.cap is not None:
            self._make_room(link, n)
        with self._lock:
            self.total += n
            self._holders[link] = None
            if self.cap is not None and self.total > self.cap:
                self.overflows += 1
                return False
            self.peak = max(self.peak, self.total)
            return True

    def release(self, link: Any, n: int, *, keep: bool = False) -> None:
        """``link``'s output stopped waiting (written or discarded): its ``n`` bytes go
        (``keep``: it still holds other bytes)."""
        with self._lock:
            self.total -= n
            if not keep:
                self._holders.pop(link, None)

    def _make_room(self, link: Any, n: int) -> None:
        assert self.cap is not None
        mine = bool(getattr(link, "privileged", False))
        deadline = time.monotonic() + EVICT_WAIT_S  # one for all the links dropped here
        while True:
            with self._lock:
                if self.total + n <= self.cap:
                    return
                others = [h for h in self._holders if h is not link
                          and (mine or not h.privileged)]  # fmt: skip
            others.sort(key=lambda h: (h.privileged, h.waiting_since))
            if not self._evict_first(others, deadline):
                return  # nobody else may pay: the link charged is dropped
            with self._lock:
                self.evicted += 1

    @staticmethod
    def _evict_first(links: list[Any], deadline: float) -> bool:
        """Drop the first of ``links`` (in the order they should pay) that can be. A link
        whose output lock is taken is waited for, until ``deadline`` (shared by every link
        one charge drops: two links charged at once cannot wait for each other long),
        rather than passed over for one that should pay after it: a busy loop beside the
        server must not turn "the silent one pays" into "the reader pays". Past the
        deadline, the rest are asked without waiting. Whether one was dropped."""
        why = "its output waited while the server's output budget was full"
        for h in links:
            if h.evict(why, wait=max(0.0, deadline - time.monotonic())):
                return True
        return False


@dataclass(frozen=True)
class LinkLimits:
    """What every link of one server obeys (see :class:`robocli.serving.server.Server`)."""

    protocol: str
    max_frame: int | None
    byte_timeout: float
    send_timeout: float
    max_backlog: int
    pace: bool = False
    """Handle no request while a reply waits for the peer; ``max_backlog`` then bounds what
    is queued beyond that one reply."""
    strict: bool = False
    """A stream that loses its framing (bytes the framer must skip, a partial frame
    abandoned) is closed rather than rescanned: for protocols without a sync marker."""
    handshake_timeout: float | None = None
    """A TCP link not :meth:`~Link.establish`-ed this many seconds after it opened is closed."""
    budget: OutputBudget | None = None
    framer: Callable[[], Any] | None = None
    """Makes each link's framer instead of the C framer of ``protocol`` (a Python framer
    with the same ``feed``/``pending``/``reset``/``stats``, for a line protocol)."""


@dataclass
class ServerLinkStats:
    """Counters of one link, or summed over a server's links (:meth:`Server.stats`)."""

    frames: int = 0  #: complete frames handed to the session
    bytes_in: int = 0
    bytes_out: int = 0  #: bytes the kernel (or the pty) accepted
    dropped_bytes: int = 0  #: input bytes skipped: garbage, bad frames, abandoned partials
    bad_checksums: int = 0
    oversize: int = 0  #: frame headers announcing more than ``max_frame`` (dropped)
    abandoned: int = 0  #: partial frames given up after ``byte_timeout``
    tx_dropped: int = 0  #: output bytes discarded (pty line full, link dropped)
    session_errors: int = 0  #: exceptions raised by the session (the link is then dropped)

    def add(self, other: ServerLinkStats) -> None:
        for f in fields(self):
            setattr(self, f.name, getattr(self, f.name) + getattr(other, f.name))
