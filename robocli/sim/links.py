"""Links of the serving layer: one client's byte stream (TCP or pty) and its thread.

A :class:`Link` frames what it receives with the C framer (bounded by ``max_frame``), hands
each complete frame to its session and writes the replies inline from its own thread. A
partial frame with no new byte for ``byte_timeout`` is abandoned: its first byte is dropped and
the rest rescanned. :meth:`Link.send` never blocks: output the peer cannot take now waits in a
bounded backlog, and a peer that leaves it unread for ``send_timeout`` is dropped. With nothing
queued, a reply is written straight from the caller's buffer and only what the peer could not
take yet is copied into the backlog (a large reply, a camera frame, is not copied whole). Pushes
from another thread (a ticker) are flushed by the next push or by the link's own thread.

Used through :class:`robocli.sim.serving.Server`; nothing here is global.
"""

from __future__ import annotations

import errno
import logging
import os
import select
import socket
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

from robocli.core import Framer
from robocli.errors import TransportError

if TYPE_CHECKING:
    from robocli.sim.serving import Session

__all__ = ["DONTWAIT", "Link", "LinkLimits", "LinkStats", "PtyLink", "TcpLink"]

log = logging.getLogger("robocli.sim.serving")

RECV_SIZE = 65536  #: bytes per recv
MAX_PARTS = 512  #: buffers one gathered write takes (below every platform's IOV_MAX)
DONTWAIT = getattr(socket, "MSG_DONTWAIT", 0)  #: 0 where the platform has no such flag


@dataclass(frozen=True)
class LinkLimits:
    """What every link of one server obeys (see :class:`robocli.sim.serving.Server`)."""

    protocol: str
    max_frame: int | None
    byte_timeout: float
    send_timeout: float
    max_backlog: int


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


# ============================================================================ links


class Link:
    """One byte stream to one client: a TCP connection or a pty. Created by :class:`Server`.

    :meth:`send` may be called from any thread. Everything else runs in the link's own
    thread.
    """

    def __init__(self, limits: LinkLimits, name: str, on_end: Callable[[Link], None]) -> None:
        self.name = name
        self._limits = limits
        self._on_end = on_end
        self._framer = Framer(limits.protocol, limits.max_frame)
        self._rx_lock = threading.Lock()  # framer and input counters
        self._tx_lock = threading.Lock()  # output and its backlog
        self._tail = bytearray()  # the bytes the framer holds (a partial frame)
        self._last_rx = time.monotonic()
        self._backlog = bytearray()
        self._backlog_since = 0.0
        self._replies: list[bytes] = []  # replies of the frames being dispatched (link thread)
        self._closed = False
        self._stats = LinkStats()
        self.session: Session | None = None

    # ---------------------------------------------------------------- any thread

    @property
    def alive(self) -> bool:
        """False once the link was dropped or closed."""
        return not self._closed

    def send(self, data: bytes) -> bool:
        """Queue ``data`` and write what the peer can take now; never blocks.

        Returns False when the link is gone (the data is then discarded).
        """
        if not data:
            return not self._closed
        with self._tx_lock:
            if self._closed:
                self._stats.tx_dropped += len(data)
                return False
            if self._backlog:
                self._backlog += data
                return self._flush_locked(time.monotonic())
            return self._send_direct(data)

    def send_parts(self, parts: Sequence[bytes | memoryview]) -> bool:
        """Send one reply made of several contiguous buffers (a header, then records) without
        joining them: one gathered write where the link supports it, and only what the peer
        did not take is copied into the backlog. Call it from the link's own thread while it
        dispatches frames (a session's ``on_frame``): the replies already returned for earlier
        frames go first. Returns False when the link is gone."""
        if self._replies:
            self.send(b"".join(self._replies))
            self._replies.clear()
        views = [memoryview(p).cast("B") for p in parts]
        total = sum(v.nbytes for v in views)
        with self._tx_lock:
            if self._closed:
                self._stats.tx_dropped += total
                return False
            if self._backlog or len(views) > MAX_PARTS:
                for v in views:
                    self._backlog += v
                return self._flush_locked(time.monotonic())
            try:
                n = self._write_parts(views)
            except OSError as exc:
                log.info("%s: write failed (%s); dropping the link", self.name, exc)
                self._mark_closed("write failed")
                return False
            if n == total:
                return True
            skip = n
            for v in views:  # back-log what the peer did not take
                if skip < v.nbytes:
                    self._backlog += v[skip:]
                skip = max(0, skip - v.nbytes)
            return self._backlog_checked(n, time.monotonic())

    def close(self) -> None:
        """Drop the link: its thread sees the end of the stream and finishes."""
        with self._tx_lock:
            self._mark_closed("closed")

    @property
    def stats(self) -> LinkStats:
        """A copy of the counters (thread-safe)."""
        with self._rx_lock:
            fs = self._framer.stats
            s = LinkStats(**{f.name: getattr(self._stats, f.name) for f in fields(LinkStats)})
        s.frames = fs.frames
        s.dropped_bytes = fs.dropped_bytes + self._stats.abandoned
        s.bad_checksums, s.oversize = fs.bad_checksums, fs.bad_lengths
        return s

    # ---------------------------------------------------------------- output (tx lock held)

    def _write_locked(self, data: bytes | bytearray) -> int | None:
        """Write what the peer takes now; None (and the link dropped) if the write failed."""
        try:
            return self._write_now(data)
        except OSError as exc:
            log.info("%s: write failed (%s); dropping the link", self.name, exc)
            self._mark_closed("write failed")
            return None

    def _send_direct(self, data: bytes | bytearray) -> bool:
        """Nothing queued: write from ``data`` itself, back-log only the rest."""
        n = self._write_locked(data)
        if n is None:
            return False
        if n == len(data):
            return True
        self._backlog += memoryview(data)[n:]  # the only copy: what the peer did not take
        return self._backlog_checked(n, time.monotonic())

    def _flush_locked(self, now: float) -> bool:
        n = self._write_locked(self._backlog)
        if n is None:
            return False
        del self._backlog[:n]
        return self._backlog_checked(n, now)

    def _backlog_checked(self, n: int, now: float) -> bool:
        """After ``n`` bytes went out: restart or enforce the backlog's deadline and bound."""
        if not self._backlog:
            self._backlog_since = 0.0
            return True
        if n or not self._backlog_since:
            self._backlog_since = now  # the client read something: its deadline restarts
        limits = self._limits
        if len(self._backlog) > limits.max_backlog:
            log.warning(
                "%s: %d bytes unread by the client; dropping it", self.name, len(self._backlog)
            )
            self._mark_closed("backlog full")
            return False
        if now - self._backlog_since > limits.send_timeout:
            log.warning(
                "%s: client has not read for %.1f s; dropping it", self.name, limits.send_timeout
            )
            self._mark_closed("send timeout")
            return False
        return True

    def _mark_closed(self, why: str) -> None:
        if self._closed:
            return
        self._closed = True
        self._stats.tx_dropped += len(self._backlog)
        self._backlog.clear()
        log.debug("%s: link closing (%s)", self.name, why)
        self._interrupt()

    def _write_now(self, data: bytes | bytearray) -> int:  # pragma: no cover - overridden
        """Write what can go without blocking; the bytes consumed from ``data``."""
        raise NotImplementedError

    def _write_parts(self, views: list[memoryview]) -> int:
        """:meth:`_write_now` of the buffers one after the other (a link with a gathered
        write overrides it)."""
        return self._write_now(b"".join(views))

    def _interrupt(self) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    # ---------------------------------------------------------------- input (link thread)

    def _feed(self, data: bytes, now: float) -> bytes:
        """Frame ``data``; the session's replies, joined."""
        with self._rx_lock:
            self._last_rx = now
            self._stats.bytes_in += len(data)
            frames = self._framer.feed(data)
            pending = self._framer.pending
            tail = self._tail
            if pending:
                tail += data
                del tail[:-pending]
            elif tail:
                tail.clear()
        return self._dispatch(frames, now) if frames else b""

    def _dispatch(self, frames: list[bytes], now: float) -> bytes:
        session = self.session
        assert session is not None  # set before the thread starts
        replies = self._replies  # send_parts sends these first
        for f in frames:
            reply = session.on_frame(f, now)
            if reply:
                replies.append(reply)
        out = b"".join(replies)
        replies.clear()
        return out

    def _partial_deadline(self) -> float | None:
        """When the partial frame held now is abandoned (None: nothing held)."""
        return self._last_rx + self._limits.byte_timeout if self._tail else None

    def _abandon_partial(self, now: float) -> bytes:
        """Drop the first byte of a partial frame that stopped coming; rescan the rest."""
        with self._rx_lock:
            stale = bytes(self._tail)
            self._framer.reset()
            self._tail.clear()
            self._stats.abandoned += 1
        log.debug("%s: partial frame abandoned: %s", self.name, stale[:8].hex(" "))
        return self._feed(stale[1:], now) if len(stale) > 1 else b""

    def _serve(self) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    def _run(self) -> None:
        """The link thread: serve until the stream ends, then report the end (``on_end``)."""
        try:
            self._serve()
        except Exception:  # the session raised: log it whole, count it, drop this link only
            log.exception("%s: session failed; dropping the link", self.name)
            with self._rx_lock:
                self._stats.session_errors += 1
        finally:
            with self._tx_lock:
                self._mark_closed("link thread ending")
            self._release()
            self._on_end(self)

    def _release(self) -> None:  # pragma: no cover - overridden
        raise NotImplementedError


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
        self, limits: LinkLimits, sock: socket.socket, name: str, on_end: Callable[[Link], None]
    ) -> None:
        super().__init__(limits, name, on_end)
        self.sock = sock
        if not DONTWAIT:  # Windows: no per-call non-blocking send; bound a blocking one
            ms = int(limits.send_timeout * 1000)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDTIMEO, ms)

    def _write_now(self, data: bytes | bytearray) -> int:
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
        while not self._closed:
            deadline = self._partial_deadline()
            backlog = bool(self._backlog)
            if deadline is not None or backlog:
                # slow path: a partial frame to time out, or output to flush when writable
                now = time.monotonic()
                ends = [deadline] if deadline is not None else []
                if backlog:
                    ends.append(self._backlog_since + limits.send_timeout + 0.001)
                timeout = max(0.0, min(ends) - now)
                readable, _ = _wait(fd, read=True, write=backlog, timeout=timeout)
                if backlog:
                    with self._tx_lock:
                        if not self._closed and self._backlog:
                            self._flush_locked(time.monotonic())
                if not readable:
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

    def _release(self) -> None:
        self.sock.close()


class PtyLink(Link):
    """The master side of a pseudo-terminal in raw mode (a serial line)."""

    def __init__(
        self, limits: LinkLimits, master: int, slave: int, path: str,
        on_end: Callable[[Link], None],
    ) -> None:  # fmt: skip
        super().__init__(limits, f"pty {path}", on_end)
        self.master, self.slave = master, slave
        self._wake_r, self._wake_w = os.pipe()

    def _write_now(self, data: bytes | bytearray) -> int:
        """What the pty cannot take now is dropped, as on a serial line with nobody
        listening: the backlog is always emptied."""
        view = memoryview(data)
        sent = 0
        try:
            while sent < len(view):
                sent += os.write(self.master, view[sent:])
        except BlockingIOError:
            self._stats.tx_dropped += len(view) - sent
            log.debug("%s: line full: dropped %d bytes", self.name, len(view) - sent)
        finally:
            view.release()
        self._stats.bytes_out += sent
        return len(data)

    def _interrupt(self) -> None:
        try:
            os.write(self._wake_w, b"x")
        except OSError:
            pass  # already released

    def _serve(self) -> None:
        master, wake = self.master, self._wake_r
        while not self._closed:
            deadline = self._partial_deadline()
            timeout = None if deadline is None else max(0.0, deadline - time.monotonic())
            ready, _, _ = select.select([master, wake], [], [], timeout)
            now = time.monotonic()
            if not ready:
                if deadline is not None and now >= deadline:
                    self.send(self._abandon_partial(now))
                continue
            if wake in ready:
                return
            try:
                data = os.read(master, RECV_SIZE)
            except BlockingIOError:
                continue
            except OSError as exc:  # EIO: no process holds the slave end right now
                if exc.errno != errno.EIO:
                    raise TransportError(f"{self.name}: read failed: {exc}") from exc
                if select.select([wake], [], [], 0.05)[0]:
                    return
                continue
            if data:
                self.send(self._feed(data, now))

    def _release(self) -> None:
        for fd in (self.master, self.slave, self._wake_r, self._wake_w):
            os.close(fd)
