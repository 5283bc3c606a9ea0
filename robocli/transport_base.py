"""What every byte stream of :mod:`robocli.transports` is: :class:`Transport`, with the
deadline of every write (:data:`WRITE_TIMEOUT`) and the helpers its kinds share. Import it
from :mod:`robocli.transports`.
"""

from __future__ import annotations

import math
import select
import threading
import time

from robocli.closing import Closing
from robocli.errors import ConnectionLost, StaleWrite, TransportError

__all__ = ["WRITE_TIMEOUT", "Transport"]


#: Default deadline of one write, in seconds: past it the peer is taken as not reading.
WRITE_TIMEOUT = 1.0


class Transport(Closing):
    """A bidirectional byte stream. Subclasses implement ``_read``/``_write``/``_close`` and,
    where they can, ``_wait_readable``.

    Every write has a deadline (:attr:`write_timeout`, about 1 s by default): a peer that stops
    reading makes :meth:`write` raise :class:`~robocli.errors.TransportError`, never hang.
    """

    url: str = ""

    def __init__(self) -> None:
        self._closed = False
        self._write_lock = threading.Lock()
        self.write_timeout = WRITE_TIMEOUT

    def read(self, size: int = 4096, timeout: float | None = None) -> bytes:
        """Return up to ``size`` bytes, ``b""`` if none arrived within ``timeout`` seconds
        (``None`` blocks, ``0`` only takes what is there). Raises :class:`ConnectionLost` once
        the stream has ended."""
        if self._closed:
            raise ConnectionLost(f"{self.url}: transport is closed")
        return self._read(size, timeout)

    def wait_readable(self, timeout: float) -> bool:
        """True when a :meth:`read` would return data (or report the end of the stream)
        without waiting; False after ``timeout`` seconds. Consumes nothing."""
        if self._closed:
            raise ConnectionLost(f"{self.url}: transport is closed")
        return self._wait_readable(timeout)

    def fileno(self) -> int | None:
        """The file descriptor to wait on with ``poll``/``select``, or None when the stream
        has none (pyserial URL handlers, wrapped transports): use :meth:`wait_readable`."""
        return None

    def write(
        self, data: bytes, timeout: float | None = None, *, not_after: float | None = None
    ) -> None:
        """Send all of ``data`` within ``timeout`` seconds (default :attr:`write_timeout`),
        else raise :class:`TransportError`. Thread-safe: writes from several threads never
        interleave; waiting for another thread's write counts against the deadline.
        ``not_after``: the monotonic time after which ``data`` must not begin to go out
        (it would be stale: the writer stalled); checked right before the first byte is
        handed to the system, :class:`StaleWrite` then, and nothing is sent."""
        if self._closed:
            raise ConnectionLost(f"{self.url}: transport is closed")
        limit = self.write_timeout if timeout is None else timeout
        deadline = time.monotonic() + limit
        if not self._write_lock.acquire(timeout=max(limit, 0.0)):
            raise TransportError(
                f"{self.url}: write blocked for {limit:g} s by another write "
                "(the peer is not reading)"
            )
        try:
            if self._closed:
                raise ConnectionLost(f"{self.url}: transport is closed")
            _check_fresh(self.url, not_after)
            self._write(bytes(data), deadline)
        finally:
            self._write_lock.release()

    def close(self) -> None:
        """Close the stream; idempotent, never waits for a blocked write."""
        if not self._closed:
            self._closed = True
            self._close()

    @property
    def closed(self) -> bool:
        return self._closed

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.url}{' closed' if self._closed else ''}>"

    # -- to implement
    def _read(self, size: int, timeout: float | None) -> bytes:
        raise NotImplementedError

    def _write(self, data: bytes, deadline: float) -> None:
        raise NotImplementedError

    def _close(self) -> None:
        raise NotImplementedError

    def _wait_readable(self, timeout: float) -> bool:
        """Fallback for streams without a file descriptor: look every 2 ms."""
        deadline = time.monotonic() + timeout
        while True:
            if self._pending_bytes():
                return True
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            time.sleep(min(0.002, left))

    def _pending_bytes(self) -> int:
        raise NotImplementedError


def _check_fresh(url: str, not_after: float | None) -> None:
    """Raise :class:`StaleWrite` when it is past ``not_after`` (a write's latest start)."""
    if not_after is not None:
        late = time.monotonic() - not_after
        if late > 0:
            raise StaleWrite(f"{url}: write not sent: it was due {late:.3f} s earlier "
                             "(the writer stalled)")  # fmt: skip


def _write_timed_out(url: str, sent: int, total: int) -> TransportError:
    return TransportError(
        f"{url}: write timed out ({sent} of {total} bytes sent; the peer is not reading)"
    )


def _poll(fd: int, events: int, timeout: float | None) -> bool:
    """Wait until ``fd`` has one of ``events`` (or an error/hang-up); ``None`` waits forever."""
    poller = select.poll()
    poller.register(fd, events)
    ms = None if timeout is None else max(0, math.ceil(timeout * 1000))
    while True:
        try:
            return bool(poller.poll(ms))
        except InterruptedError:  # pragma: no cover - PEP 475 retries already
            continue
