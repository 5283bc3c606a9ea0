""":class:`Places`: who may hold the hub's client places, and who gives one up.

Without a token every client is equal, as in ros4mat: ``max_clients`` places, first come
first served. With a token, a peer without it must not be able to take the hub away from
those who have it:

* ``reserved`` places are kept for clients that presented the token: the others hold at most
  ``max_clients - reserved``, and at most ``max_per_address`` from one address;
* a client with the token that finds the hub full takes the place of the client without it
  that has been idle longest (closed; its buffers are kept, detached, as for any client gone
  without QUIT);
* a client without the token that sends no request for ``idle_timeout`` seconds is closed
  (:meth:`Places.expire`, called by the hub's expiry ticker). Clients with the token keep
  their place however long they are idle.

Thread-safe; knows nothing of the wire.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Protocol

__all__ = ["Holder", "Places"]

log = logging.getLogger("robocli.hub_server")

BUSY_REASON = "hub full: too many clients"
BUSY_UNAUTHORIZED = "hub full for clients without the token"


class Holder(Protocol):
    """A connection holding a place (the ros4mat session)."""

    authorized: bool
    last_request: float  #: monotonic time of its last request
    address: str  #: its peer's address (no port)

    def drop(self, why: str) -> None:
        """Close the connection (its end frees the place)."""
        ...


class Places:
    """The client places of one hub (see the module docstring)."""

    def __init__(self, max_clients: int, *, token: bool, reserved: int, max_per_address: int,
                 idle_timeout: float) -> None:  # fmt: skip
        self.max_clients, self.token = max_clients, token
        self.reserved, self.max_per_address = reserved, max_per_address
        self.idle_timeout = idle_timeout
        self.evicted = 0  #: clients without the token closed to give their place to one with it
        self.expired = 0  #: clients without the token closed for being idle
        self._held: dict[Holder, None] = {}
        self._lock = threading.Lock()

    def __len__(self) -> int:
        return len(self._held)

    def take(self, holder: Holder) -> str | None:
        """A place for ``holder``: None, or why there is none (``holder.authorized`` decides
        which places it may have)."""
        with self._lock:
            if holder in self._held:
                return None
            refused = self._refusal(holder)
            if refused is None:
                self._held[holder] = None
            return refused

    def give_back(self, holder: Holder) -> None:
        """``holder``'s connection ended (idempotent)."""
        with self._lock:
            self._held.pop(holder, None)

    def expire(self, now: float | None = None) -> int:
        """Close the clients without the token idle for ``idle_timeout``; how many."""
        if not self.token:
            return 0
        now = time.monotonic() if now is None else now
        with self._lock:
            idle = [h for h in self._held
                    if not h.authorized and now - h.last_request >= self.idle_timeout]  # fmt: skip
            for h in idle:
                del self._held[h]
            self.expired += len(idle)
        for h in idle:
            h.drop(f"no request for {self.idle_timeout:g} s (no token)")
        return len(idle)

    def _refusal(self, holder: Holder) -> str | None:
        """Why ``holder`` gets no place now (lock held); None: it may take one, a place
        having been made for it if it has the token."""
        full = len(self._held) >= self.max_clients
        if not self.token:
            return BUSY_REASON if full else None
        if holder.authorized:
            return BUSY_REASON if full and not self._evict_for(holder) else None
        others = [h for h in self._held if not h.authorized]
        if len(others) >= self.max_clients - self.reserved:
            return BUSY_UNAUTHORIZED if self.reserved else BUSY_REASON
        if full:
            return BUSY_REASON
        if sum(h.address == holder.address for h in others) >= self.max_per_address:
            return f"{BUSY_UNAUTHORIZED} from {holder.address}"
        return None

    def _evict_for(self, holder: Holder) -> bool:
        """Close the client without the token idle longest for ``holder`` (lock held)."""
        others = [h for h in self._held if not h.authorized]
        if not others:
            return False
        victim = min(others, key=lambda h: h.last_request)
        del self._held[victim]
        self.evicted += 1
        victim.drop("its place went to a client with the token")
        return True
