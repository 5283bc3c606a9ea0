"""A link over one TCP connection (:class:`TcpLink`).

Part of :mod:`robocli.serving.links` (import from there).
"""

from __future__ import annotations

import logging
import select
import socket
import threading
import time
from collections.abc import Callable

from robocli.serving.links.base import RECV_SIZE, Link
from robocli.serving.links.limits import LinkLimits

log = logging.getLogger("robocli.serving.server")

DONTWAIT = getattr(socket, "MSG_DONTWAIT", 0)  #: 0 where the platform has no such flag
LINGER_S = 0.5  #: a link ending after a last reply reads (and discards) this long at most
_RDHUP: int = getattr(select, "POLLRDHUP", 0)


def _wait(fd: int, *, read: bool, write: bool, timeout: float | None) -> tuple[bool, bool]:
    """Wait until ``fd`` is readable/writable or ``timeout`` passes (None: forever)."""
    if hasattr(select, "poll"):
        p = select.poll()
        p.register(fd, (select.POLLIN if read else 0) | (select.POLLOUT if write else 0))
        events = p.poll(None if timeout is None else max(0, int(timeout * 1000.0 + 0.999)))
        mask = events[0][1] if events else 0
        bad = select.POLLERR | select.POLLHUP | select.POLLNVAL
        return bool(mask & (select.POLLIN | bad)), bool(mask & (select.POLLOUT | bad))
    r, w, _ = select.select([fd] if read else [], [fd] if write else [], [], timeout)
    return bool(r), bool(w)


class TcpLink(Link):
    """A TCP connection; its thread blocks in ``recv`` and replies inline."""

    def __init__(
        self, limits: LinkLimits, sock: socket.socket, name: str, on_end: Callable[[Link], None],
        address: str = "",
    ) -> None:  # fmt: skip
        super().__init__(limits, name, on_end)
        self.sock = sock
        self.address = address
        self._fd_lock = threading.Lock()  # the socket is not closed while another thread polls
        self._released = False
        if not DONTWAIT:  # Windows: no per-call non-blocking send; bound a blocking one
            ms = int(limits.send_timeout * 1000)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDTIMEO, ms)

    def _poll_now(self, events: int) -> int:
        """The socket's poll events now (0 where poll is missing); POLLNVAL once released."""
        with self._fd_lock:
            if self._released:
                return select.POLLNVAL if hasattr(select, "POLLNVAL") else 1
            if not hasattr(select, "poll"):
                return 0
            p = select.poll()
            p.register(self.sock.fileno(), events)
            got = p.poll(0)
            return got[0][1] if got else 0

    def peer_closed(self) -> bool:
        if not self.alive:
            return True
        bad = select.POLLERR | select.POLLHUP | select.POLLNVAL if hasattr(select, "poll") else 0
        if _RDHUP:
            return bool(self._poll_now(_RDHUP) & (_RDHUP | bad))
        with self._fd_lock:  # no POLLRDHUP: the end of the stream, if nothing is unread
            if self._released:
                return True
            try:
                return self.sock.recv(1, socket.MSG_PEEK | DONTWAIT) == b""
            except (BlockingIOError, InterruptedError, TimeoutError):
                return False
            except OSError:
                return True

    def idle(self) -> bool:
        return super().idle() and not (
            hasattr(select, "poll") and self._poll_now(select.POLLIN) & select.POLLIN
        )

    def _write_now(self, data: bytes | bytearray | memoryview) -> int:
        try:
            n = self.sock.send(data, DONTWAIT)
        except (TimeoutError, BlockingIOError, InterruptedError):
            return 0
        self._stats.bytes_out += n
        return n

    def _write_parts(self, views: list[memoryview]) -> int:
        if not DONTWAIT or not hasattr(self.sock, "sendmsg"):
            return super()._write_parts(views)
        try:
            n = self.sock.sendmsg(views, (), DONTWAIT)
        except (TimeoutError, BlockingIOError, InterruptedError):
            return 0
        self._stats.bytes_out += n
        return n

    def _interrupt(self) -> None:
        try:
            self.sock.shutdown(socket.SHUT_RDWR)  # wakes the thread blocked in recv
        except OSError:
            pass  # already disconnected

    def _serve(self) -> None:
        sock, fd, limits = self.sock, self.sock.fileno(), self._limits
        recv, feed, send = sock.recv, self._feed, self.send
        handshake = limits.handshake_timeout
        while not self._closed:
            if not self.established and handshake is not None:
                if time.monotonic() >= self.opened + handshake:
                    log.info("%s: no handshake within %g s; closing", self.name, handshake)
                    return
            pending = bool(self._out)
            if not pending and (self._held or self._unframed is not None):
                send(self._resume(time.monotonic()))  # requests held while a reply waited
                continue
            if self._ending and not pending:
                self._linger()
                return
            hold = self._ending or (pending and limits.pace)  # read no request meanwhile
            deadline = None if hold else self._partial_deadline()
            if deadline is not None or pending or not self.established:
                # slow path: a deadline to keep, or output to flush when writable
                now = time.monotonic()
                ends = [deadline] if deadline is not None else []
                if pending:
                    ends.append(self._out_since + limits.send_timeout + 0.001)
                if not self.established and handshake is not None:
                    ends.append(self.opened + handshake)
                timeout = max(0.0, min(ends) - now) if ends else None
                readable, _ = _wait(fd, read=not hold, write=pending, timeout=timeout)
                if pending:
                    with self._tx_lock:
                        if not self._closed and self._out:
                            self._flush_locked(time.monotonic())
                    if hold and not self._out:
                        self._last_rx = time.monotonic()  # we did not read: no partial's fault
                if hold or not readable:
                    now = time.monotonic()
                    if deadline is not None and now >= deadline:
                        send(self._abandon_partial(now))
                    continue
            try:
                data = recv(RECV_SIZE)  # the fast path: blocked here, reply inline below
            except OSError as exc:
                log.debug("%s: recv failed: %s", self.name, exc)
                return
            if not data:
                return
            reply = feed(data, time.monotonic())
            if reply:
                send(reply)

    def _linger(self) -> None:
        """End after a last reply: no more output, and read what the peer still sends (at
        most :data:`LINGER_S`) so that closing does not reset the reply away."""
        try:
            self.sock.shutdown(socket.SHUT_WR)
            end = time.monotonic() + LINGER_S
            while (left := end - time.monotonic()) > 0:
                readable, _ = _wait(self.sock.fileno(), read=True, write=False, timeout=left)
                if not readable or not self.sock.recv(RECV_SIZE):
                    return
        except OSError:
            return  # reset or gone: nothing more to do

    def _release(self) -> None:
        with self._fd_lock:
            self._released = True
            self.sock.close()
