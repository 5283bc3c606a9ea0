"""The link every byte stream of the serving layer is: :class:`Link` (framing, dispatch to
its session, the output queue and its bounds, the link thread's end), and the protocols of the
sessions it serves (:class:`ServerSession`, :class:`UnframedHook`).

Part of :mod:`robocli.serving.links` (import from there).
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import fields
from itertools import islice
from typing import Any, Protocol

from robocli.core import Framer
from robocli.serving.links.limits import LinkLimits, ServerLinkStats

log = logging.getLogger("robocli.serving.server")


class ServerSession(Protocol):
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
UNFRAMED_HEAD = 256  #: bytes of a stream that lost its framing shown to the session


def held_memory(views: Sequence[memoryview]) -> int:
    """Bytes of memory ``views`` keep alive: each buffer they are views of counted once and
    whole (a view of a few bytes of a pulled array holds all of the array)."""
    roots: dict[int, int] = {}
    for v in views:
        root: Any = v.obj
        while getattr(root, "base", None) is not None and hasattr(root.base, "nbytes"):
            root = root.base
        try:
            size = memoryview(root).nbytes
        except TypeError:  # not a buffer itself: count what the view shows
            size = v.nbytes
        roots[id(root)] = max(roots.get(id(root), 0), size)
    return sum(roots.values())


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
        self._framer = (
            limits.framer() if limits.framer else Framer(limits.protocol, limits.max_frame)
        )
        self._rx_lock = threading.Lock()  # framer and input counters
        self._tx_lock = threading.Lock()  # output and its queue
        self._tail = bytearray()  # the bytes the framer holds (a partial frame)
        self._last_rx = time.monotonic()
        self._out: deque[memoryview] = deque()  # output the peer has not taken yet
        self._out_bytes = 0
        self._out_since = 0.0
        self._charged = 0  # bytes of memory the waiting output holds, charged to the budget
        self._reserved = 0  # bytes charged for a reply being built (reserve)
        self.privileged = False
        """Set by the session for a client that proved its rights (a hub's token): the
        server's output budget drops the others first and never this one for them."""
        self._replies: list[bytes] = []  # replies of the frames being dispatched (link thread)
        self._held: list[bytes] = []  # frames waiting for a reply to go out (pace)
        self._unframed: bytes | None = None  # where the stream lost its framing (strict)
        self._ending = False  # read nothing more; end once the output is out
        self._closed = False
        self._ended = threading.Event()
        self._stats = ServerLinkStats()
        self.session: ServerSession | None = None

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
    def waiting_since(self) -> float:
        """Since when (monotonic s) the peer has taken none of the output waiting for it
        (now when nothing waits: a link building a reply is not one that stopped reading)."""
        return self._out_since if self._out else time.monotonic()

    def evict(self, why: str, wait: float = 0.0) -> bool:
        """Drop the link for another one's sake. Its output lock is taken first, waiting at
        most ``wait`` s for it (its own thread may hold it, in a write, or descheduled in
        one). Whether it was dropped (not when closed already or its lock stayed taken)."""
        if not self._tx_lock.acquire(timeout=max(0.0, wait)):
            return False
        try:
            if self._closed:
                return False
            log.warning("%s: dropped, %d bytes unread: %s", self.name, self._out_bytes, why)
            self._mark_closed("evicted")
            return True
        finally:
            self._tx_lock.release()

    def reserve(self, n: int) -> bool:
        """Charge the server's output budget ``n`` bytes the session is about to allocate
        for a reply (a pull's copy), before it does: room is made as for waiting output.
        False when there is none: the link is then dropped. Give them back with
        :meth:`unreserve` once the reply is built (its queue is charged for what waits)."""
        budget = self._limits.budget
        if budget is None or n <= 0:
            return not self._closed
        with self._tx_lock:
            if self._closed:
                return False
            self._reserved += n
            if budget.charge(self, n):
                return True
            log.warning("%s: the server's output budget (%s bytes) cannot take a reply of %d "
                        "bytes; dropping this client", self.name, budget.cap, n)  # fmt: skip
            self._mark_closed("output budget full")
            return False

    def unreserve(self) -> None:
        """Give back what :meth:`reserve` charged."""
        with self._tx_lock:
            self._release_reserved()

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
    def stats(self) -> ServerLinkStats:
        """A copy of the counters (thread-safe)."""
        with self._rx_lock:
            fs = self._framer.stats
            s = ServerLinkStats(
                **{f.name: getattr(self._stats, f.name) for f in fields(ServerLinkStats)}
            )
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
        added, kept = 0, []
        for v in views:
            if skip >= v.nbytes:
                skip -= v.nbytes
                continue
            part = v[skip:] if skip else v
            skip = 0
            self._out.append(part)
            added += part.nbytes
            kept.append(v)
        if not added:
            return True
        if not self._out_bytes:
            self._out_since = now
        self._out_bytes += added
        budget = self._limits.budget
        within = True
        if budget is not None:
            charge = held_memory(kept)
            within = budget.charge(self, charge)
            self._charged += charge
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
            self._release_charge()
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
        self._release_charge()
        self._release_reserved()
        self._out.clear()
        self._out_bytes = 0
        log.debug("%s: link closing (%s)", self.name, why)
        self._interrupt()

    def _release_reserved(self) -> None:
        if self._reserved and self._limits.budget is not None:
            self._limits.budget.release(self, self._reserved, keep=bool(self._charged))
        self._reserved = 0

    def _release_charge(self) -> None:
        """The output no longer waits: the memory it held leaves the budget (tx lock held)."""
        if self._charged and self._limits.budget is not None:
            self._limits.budget.release(self, self._charged, keep=bool(self._reserved))
        self._charged = 0

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
