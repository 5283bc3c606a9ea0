"""Links of the serving layer: one client's byte stream (TCP or pty) and its thread.

A :class:`Link` frames what it receives with the C framer (bounded by ``max_frame``), hands
each complete frame to its session and writes the replies inline from its own thread. A
partial frame with no new byte for ``byte_timeout`` is abandoned: its first byte is dropped and
the rest rescanned (with ``strict`` framing the link is closed instead). :meth:`Link.send`
never blocks: output the peer cannot take now waits in a bounded queue, and a peer that leaves
it unread for ``send_timeout`` is dropped. Nothing is copied to wait: a reply is written
straight from the caller's buffers and the queue keeps views of what the peer has not taken
yet (a large reply, a camera frame, is not copied). Pushes from another thread (a ticker) are
flushed by the next push or by the link's own thread.

With ``pace`` (request/reply protocols) a link reads and handles no request while one of its
replies waits for the peer: a client that asks without reading holds at most one reply in the
server, and its next requests wait in the kernel's buffers. An :class:`OutputBudget` bounds the
output waiting over every link of a server: a link whose output would take it over is dropped.

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
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from itertools import islice
from typing import Protocol

from robocli.core import Framer
from robocli.errors import TransportError

__all__ = [
    "DONTWAIT",
    "Link",
    "LinkLimits",
    "LinkStats",
    "OutputBudget",
    "PtyLink",
    "Session",
    "TcpLink",
    "UnframedHook",
]

log = logging.getLogger("robocli.sim.serving")


class Session(Protocol):
    """One client's protocol state machine (no sockets).

    Called from its link's thread only: :meth:`on_frame` for each complete frame, in order,
    then :meth:`on_close` once when the link ends (whatever the reason). A session shared
    with other threads (a ticker) guards its own state.
    """

    def on_frame(self, frame: bytes, now: float) -> bytes | None:
        """Handle one complete frame (header and checksum included) received at ``now``
        (monotonic seconds); return the bytes to reply at once, if any."""
        ...

    def on_close(self) -> None:
        """The link is gone (peer closed, dropped, server closing)."""
        ...


class UnframedHook(Protocol):
    """Optional for a session of a server with ``strict_framing``."""

    def on_unframed(self, head: bytes) -> bytes | None:
        """The stream lost its framing at ``head`` (the first bytes the framer could not
        take as a frame, at most 256): return a last reply, if any; the link then ends."""
        ...

RECV_SIZE = 65536  #: bytes per recv
MAX_PARTS = 512  #: buffers one gathered write takes (below every platform's IOV_MAX)
DONTWAIT = getattr(socket, "MSG_DONTWAIT", 0)  #: 0 where the platform has no such flag
LINGER_S = 0.5  #: a link ending after a last reply reads (and discards) this long at most
UNFRAMED_HEAD = 256  #: bytes of a stream that lost its framing shown to the session
_RDHUP: int = getattr(select, "POLLRDHUP", 0)


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
        self.address = ""
        """The peer's address without its port (TCP), for per-address limits."""
        self.opened = time.monotonic()
        self.established = limits.handshake_timeout is None
        """False until the session calls :meth:`establish` (when ``handshake_timeout`` is
        set): the link is pending, closed if the handshake does not come in time."""
        self._limits = limits
        self._on_end = on_end
        self._framer = Framer(limits.protocol, limits.max_frame)
        self._rx_lock = threading.Lock()  # framer and input counters
        self._tx_lock = threading.Lock()  # output and its queue
        self._tail = bytearray()  # the bytes the framer holds (a partial frame)
        self._last_rx = time.monotonic()
        self._out: deque[memoryview] = deque()  # output the peer has not taken yet
        self._out_bytes = 0
        self._out_since = 0.0
        self._replies: list[bytes] = []  # replies of the frames being dispatched (link thread)
        self._held: list[bytes] = []  # frames waiting for a reply to go out (pace)
        self._unframed: bytes | None = None  # where the stream lost its framing (strict)
        self._ending = False  # read nothing more; end once the output is out
        self._closed = False
        self._ended = threading.Event()
        self._stats = LinkStats()
        self.session: Session | None = None

    # ---------------------------------------------------------------- any thread

    @property
    def alive(self) -> bool:
        """False once the link was dropped or closed."""
        return not self._closed

    @property
    def ended(self) -> bool:
        """True once the link's thread has finished (and the server forgot the link)."""
        return self._ended.is_set()

    def wait_ended(self, timeout: float) -> bool:
        """Wait at most ``timeout`` s for the link's thread to finish; whether it did."""
        return self._ended.wait(max(0.0, timeout))

    def establish(self) -> None:
        """The session's handshake is complete: the link is no longer pending."""
        self.established = True

    def peer_closed(self) -> bool:
        """Whether the peer has closed its end (the link's thread may not know it yet)."""
        return False

    def idle(self) -> bool:
        """Whether the peer has sent nothing at all yet."""
        return self._stats.bytes_in == 0

    @property
    def pending_output(self) -> int:
        """Bytes of output waiting for the peer."""
        return self._out_bytes

    def send(self, data: bytes | bytearray | memoryview) -> bool:
        """Queue ``data`` and write what the peer can take now; never blocks.

        Returns False when the link is gone (the data is then discarded).
        """
        if not data:
            return not self._closed
        view = memoryview(data if type(data) is bytes else bytes(data))
        with self._tx_lock:
            if self._closed:
                self._stats.tx_dropped += view.nbytes
                return False
            return self._send_locked([view])

    def send_parts(self, parts: Sequence[bytes | memoryview]) -> bool:
        """Send one reply made of several contiguous buffers (a header, then records) without
        joining them: one gathered write where the link supports it. What the peer does not
        take now waits as views of these buffers: they must not change afterwards. Call it
        from the link's own thread while it dispatches frames (a session's ``on_frame``): the
        replies already returned for earlier frames go first. Returns False when the link is
        gone."""
        views = [memoryview(p).cast("B") for p in parts]
        if self._replies:
            views.insert(0, memoryview(b"".join(self._replies)))
            self._replies.clear()
        with self._tx_lock:
            if self._closed:
                self._stats.tx_dropped += sum(v.nbytes for v in views)
                return False
            return self._send_locked(views)

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

    def _send_locked(self, views: list[memoryview]) -> bool:
        """Write ``views`` after what waits already; queue what the peer does not take."""
        now = time.monotonic()
        if self._out or len(views) > MAX_PARTS:
            return self._queue(views, 0, now) and self._flush_locked(now)
        try:
            n = self._write_parts(views)
        except OSError as exc:
            log.info("%s: write failed (%s); dropping the link", self.name, exc)
            self._mark_closed("write failed")
            return False
        if n == sum(v.nbytes for v in views):
            return True
        return self._queue(views, n, now)

    def _queue(self, views: list[memoryview], skip: int, now: float) -> bool:
        """Queue ``views`` but their first ``skip`` bytes (taken by the peer); enforce the
        link's bound and the server's budget."""
        exempt = self._limits.pace and not self._out  # one reply waits, whatever its size
        added = 0
        for v in views:
            if skip >= v.nbytes:
                skip -= v.nbytes
                continue
            part = v[skip:] if skip else v
            skip = 0
            self._out.append(part)
            added += part.nbytes
        if not added:
            return True
        if not self._out_bytes:
            self._out_since = now
        self._out_bytes += added
        budget = self._limits.budget
        within = budget.add(added) if budget is not None else True
        if not exempt and self._out_bytes > self._limits.max_backlog:
            log.warning("%s: %d bytes unread by the client; dropping it", self.name,
                        self._out_bytes)  # fmt: skip
            self._mark_closed("backlog full")
            return False
        if not within:
            log.warning("%s: the server's output budget (%s bytes) is full; dropping this "
                        "client (%d bytes unread)", self.name, budget and budget.cap,
                        self._out_bytes)  # fmt: skip
            self._mark_closed("output budget full")
            return False
        return True

    def _flush_locked(self, now: float) -> bool:
        """Write what waits, as far as the peer takes it; enforce ``send_timeout``."""
        out = self._out
        if not out:
            return True
        try:
            n = self._write_parts(list(islice(out, MAX_PARTS)))
        except OSError as exc:
            log.info("%s: write failed (%s); dropping the link", self.name, exc)
            self._mark_closed("write failed")
            return False
        if n:
            self._out_bytes -= n
            if self._limits.budget is not None:
                self._limits.budget.sub(n)
            while n:
                v = out[0]
                if n >= v.nbytes:
                    out.popleft()
                    n -= v.nbytes
                else:
                    out[0] = v[n:]
                    n = 0
            self._out_since = now  # the client read something: its deadline restarts
        if not out:
            return True
        if now - self._out_since > self._limits.send_timeout:
            log.warning("%s: client has not read for %.1f s; dropping it", self.name,
                        self._limits.send_timeout)  # fmt: skip
            self._mark_closed("send timeout")
            return False
        return True

    def _mark_closed(self, why: str) -> None:
        if self._closed:
            return
        self._closed = True
        self._stats.tx_dropped += self._out_bytes
        if self._limits.budget is not None and self._out_bytes:
            self._limits.budget.sub(self._out_bytes)
        self._out.clear()
        self._out_bytes = 0
        log.debug("%s: link closing (%s)", self.name, why)
        self._interrupt()

    def _write_now(self, data: bytes | bytearray | memoryview) -> int:  # pragma: no cover
        """Write what can go without blocking; the bytes consumed from ``data``."""
        raise NotImplementedError

    def _write_parts(self, views: list[memoryview]) -> int:
        """:meth:`_write_now` of the buffers one after the other (a link with a gathered
        write overrides it)."""
        return self._write_now(views[0] if len(views) == 1 else b"".join(views))

    def _interrupt(self) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    # ---------------------------------------------------------------- input (link thread)

    def _feed(self, data: bytes, now: float) -> bytes:
        """Frame ``data``; the session's replies, joined."""
        strict = self._limits.strict
        with self._rx_lock:
            self._last_rx = now
            self._stats.bytes_in += len(data)
            before = len(self._tail)
            frames = self._framer.feed(data)
            pending = self._framer.pending
            tail = self._tail
            lost = strict and before + len(data) - pending - sum(map(len, frames)) > 0
            stream = bytes(tail) + data if lost else b""  # what the framer scanned
            if pending:
                tail += data
                del tail[:-pending]
            elif tail:
                tail.clear()
        if lost:
            return self._lost_framing(stream, frames, now)
        return self._dispatch(frames, now) if frames else b""

    def _lost_framing(self, stream: bytes, frames: list[bytes], now: float) -> bytes:
        """Strict framing: the framer skipped bytes. The frames before the skip are served,
        the session may answer the bytes where framing was lost, then the link ends (what
        the framer found after a skip may be a phantom request)."""
        pos, good = 0, []
        for f in frames:
            if not stream.startswith(f, pos):
                break  # framed after the skip
            good.append(f)
            pos += len(f)
        self._unframed = stream[pos : pos + UNFRAMED_HEAD]
        log.info("%s: stream lost its framing at %s; closing after %d requests", self.name,
                 self._unframed[:8].hex(" "), len(good))  # fmt: skip
        self._held = good + self._held
        return self._resume(now)

    def _dispatch(self, frames: list[bytes], now: float) -> bytes:
        session = self.session
        assert session is not None  # set before the thread starts
        replies = self._replies  # send_parts sends these first
        pace = self._limits.pace
        for i, f in enumerate(frames):
            if pace and self._out:  # a reply waits for the peer: handle no more for now
                self._held = frames[i:] + self._held
                break
            reply = session.on_frame(f, now)
            if reply:
                replies.append(reply)
        out = b"".join(replies)
        replies.clear()
        return out

    def _resume(self, now: float) -> bytes:
        """Handle the frames held while a reply waited; then, where the framing was lost,
        the session's last word before the link ends."""
        frames, self._held = self._held, []
        out = self._dispatch(frames, now) if frames else b""
        if self._held or self._unframed is None:
            return out
        head, self._unframed = self._unframed, None
        hook = getattr(self.session, "on_unframed", None)
        last = hook(head) if hook is not None else None
        self._ending = True
        return out + last if last else out

    def _partial_deadline(self) -> float | None:
        """When the partial frame held now is abandoned (None: nothing held)."""
        return self._last_rx + self._limits.byte_timeout if self._tail else None

    def _abandon_partial(self, now: float) -> bytes:
        """Drop the first byte of a partial frame that stopped coming; rescan the rest (with
        strict framing: end the link)."""
        with self._rx_lock:
            stale = bytes(self._tail)
            self._framer.reset()
            self._tail.clear()
            self._stats.abandoned += 1
        if self._limits.strict:
            log.info("%s: partial frame abandoned (%s); closing", self.name,
                     stale[:8].hex(" "))  # fmt: skip
            self._ending = True
            return b""
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
            try:
                with self._tx_lock:
                    self._mark_closed("link thread ending")
                self._release()
                self._on_end(self)
            finally:
                self._ended.set()

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


class PtyLink(Link):
    """The master side of a pseudo-terminal in raw mode (a serial line)."""

    def __init__(
        self, limits: LinkLimits, master: int, slave: int, path: str,
        on_end: Callable[[Link], None],
    ) -> None:  # fmt: skip
        super().__init__(limits, f"pty {path}", on_end)
        self.established = True  # one line, no handshake to wait for
        self.master, self.slave = master, slave
        self._wake_r, self._wake_w = os.pipe()

    def _write_now(self, data: bytes | bytearray | memoryview) -> int:
        """What the pty cannot take now is dropped, as on a serial line with nobody
        listening: the queue is always emptied."""
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
            if self._held or self._unframed is not None:
                self.send(self._resume(time.monotonic()))
                continue
            if self._ending:
                return
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
