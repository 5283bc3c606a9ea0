"""What every link of one server obeys and counts: its limits (:class:`LinkLimits`), the
output budget shared by the server's links (:class:`OutputBudget`) and the counters
(:class:`LinkStats`).

Part of :mod:`robocli.sim.links` (import from there).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any


class OutputBudget:
    """Bytes of output waiting for their peers, summed over the links of one server.

    ``cap``: the most that may wait at once (None: no bound). A link whose queued output
    takes the total over it is dropped at once, which frees that output. :attr:`peak` is the
    most that ever waited at once (within the cap). Thread-safe.
    """

    def __init__(self, cap: int | None = None) -> None:
        if cap is not None and cap <= 0:
            raise ValueError("the output budget must be > 0 bytes")
        self.cap = cap
        self.total = 0
        self.peak = 0
        self.overflows = 0  #: links dropped because the budget was full
        self._lock = threading.Lock()

    def add(self, n: int) -> bool:
        """Count ``n`` more bytes waiting; False when that takes the total over the cap."""
        with self._lock:
            self.total += n
            if self.cap is not None and self.total > self.cap:
                self.overflows += 1
                return False
            self.peak = max(self.peak, self.total)
            return True

    def sub(self, n: int) -> None:
        """``n`` bytes stopped waiting (written or discarded)."""
        with self._lock:
            self.total -= n


@dataclass(frozen=True)
class LinkLimits:
    """What every link of one server obeys (see :class:`robocli.sim.serving.Server`)."""

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
class LinkStats:
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

    def add(self, other: LinkStats) -> None:
        for f in fields(self):
            setattr(self, f.name, getattr(self, f.name) + getattr(other, f.name))
