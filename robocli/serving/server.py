"""The serving layer of the built-in simulators and the hub server: TCP and pty links and
their limits.

A simulator (or the hub) is a :class:`ServerSession` per client link plus whatever it shares
between them (its robot). This module owns everything about bytes on the wire, so the
sessions never see a socket:

* **TCP**: a listener thread accepts; each link has **one thread, blocking in** ``recv``, that
  frames the bytes, calls :meth:`ServerSession.on_frame` for each complete frame and writes the
  replies **inline** from that same thread (no hand-off on the request/reply path).
* **pty**: a pseudo-terminal in raw mode, served by one such link thread.
* **Limits**: ``max_clients`` links at once; a client beyond it gets
  :func:`~robocli.protocols.common.refusal_line` (``robocli-refused: <reason>``) and is
  closed, unless a link in place has a peer that already closed: the new client waits (a
  bounded time) for that link to end instead of being told "busy" by a client that is gone.
  ``max_frame`` bounds every frame (the link's framer drops and counts an oversize one). A
  partial frame with no new byte for ``byte_timeout`` seconds is abandoned: its first byte is
  dropped and the rest rescanned, so garbage that looks like a header never holds the commands
  behind it hostage (``strict_framing``: the link is closed instead, for a protocol without a
  sync marker, where a rescan can find phantom requests).
* **Handshakes** (``handshake_timeout``): a link is pending until its session calls
  :meth:`Link.establish`, and closed if that does not happen in time. ``max_pending`` and
  ``max_pending_per_address`` bound the pending links; a new connection beyond them closes
  the oldest pending one that has sent nothing (else the oldest), so idle connections cannot
  hold the places of clients that complete their handshake.
* **Writes never block the server.** :meth:`Link.send` is thread-safe and non-blocking: what
  the kernel cannot take now waits in a bounded queue, flushed by the next send or by the
  link's thread. A client whose output waits longer than ``send_timeout`` (or more than
  ``max_backlog`` bytes of it) is not reading: it is dropped. ``pace``: a link handles no
  request while one of its replies waits. ``output_budget`` bounds the memory held by the
  output waiting over all links (the links whose output waited longest are dropped first).
  On a pty, output the line cannot take is dropped as on a serial line with nobody
  listening, a message at a time: one the line took in part is finished as it drains.
* Periodic work (physics, SIPs, a state stream) runs on a
  :class:`~robocli.serving.ticker.Ticker` and pushes through :meth:`Link.send`.

Nothing here is global: two servers in one process are independent. :meth:`Server.close` stops
and joins every thread within a bounded time. Protocol-agnostic: the protocol name only picks
the C framer (:data:`robocli.core.PROTOCOLS`).
"""

from __future__ import annotations

import errno
import logging
import os
import select
import socket
import threading
import time
from collections.abc import Callable
from typing import Any, TypeVar

from robocli.core import Framer
from robocli.errors import TimeoutError, TransportError
from robocli.protocols.common import refusal_line
from robocli.serving.links import (
    DONTWAIT,
    Link,
    LinkLimits,
    OutputBudget,
    PtyLink,
    ServerLinkStats,
    ServerSession,
    TcpLink,
    UnframedHook,
)
from robocli.serving.ticker import JOIN_TIMEOUT_S

__all__ = [
    "BUSY_REASON",
    "SIM_HANDSHAKE_S",
    "Link",
    "OutputBudget",
    "Server",
    "ServerLinkStats",
    "ServerSession",
    "SessionFactory",
    "UnframedHook",
    "poll_until",
]

log = logging.getLogger("robocli.serving.server")

BUSY_REASON = "robot busy: another client holds it"
REFUSE_LINGER_S = 0.5  #: a refused client has this long to read the refusal line
MAX_REFUSING = 8  #: refused connections lingering at once; beyond, they are closed bare
REAP_WAIT_S = 2.0
"""A new client at a full server waits at most this long for links whose peer has already
closed to end (their threads handle what the peer sent last, then free the place)."""
LISTEN_BACKLOG = 64  #: connections the kernel holds before they are accepted
SIM_HANDSHAKE_S = 5.0
"""A simulator's single place: a TCP connection that has not completed its protocol's
handshake this long after it opened is closed, so one idle connection cannot hold it (an
ABB motion or state client may rightly stay silent: those ports have no such deadline)."""


SessionFactory = Callable[[Link], ServerSession]
S = TypeVar("S")


def poll_until(snapshot: Callable[[], S], predicate: Callable[[S], bool], timeout: float) -> S:
    """Poll ``snapshot()`` until ``predicate`` holds of it (what a simulator's
    ``wait_until`` does); raises :class:`~robocli.errors.TimeoutError` after ``timeout``
    wall seconds."""
    deadline = time.monotonic() + timeout
    while True:
        state = snapshot()
        if predicate(state):
            return state
        if time.monotonic() >= deadline:
            raise TimeoutError(f"simulator condition not met within {timeout:g} s")
        time.sleep(min(0.005, max(0.0, deadline - time.monotonic())))


# ============================================================================ the server


class Server:
    """Serves one endpoint (a TCP port or a pty) with a :class:`ServerSession` per link.

    ``session_factory(link)`` makes the session of each new link. ``protocol`` picks the
    framer (:data:`robocli.core.PROTOCOLS`), ``max_frame`` bounds its frames (bytes, header
    included; None: the protocol's default). ``max_clients``: links at once (1 for a
    single-client robot); one more is sent ``refusal_line(busy_reason)`` and closed.
    ``byte_timeout``: seconds after which a partial frame is abandoned. ``send_timeout``:
    seconds a client may leave output unread before it is dropped; ``max_backlog``: bytes
    of output it may leave unread (with ``pace``: beyond the one reply that waits).
    ``name`` prefixes the threads' names.

    ``pace``: a link handles no request while one of its replies waits for the peer.
    ``output_budget``: bytes of memory the output waiting over all links may hold at once
    (None: no bound; :class:`OutputBudget` says who is dropped to stay within it).
    ``strict_framing``: a link whose stream loses its framing is closed (after the
    session's optional :meth:`UnframedHook.on_unframed` reply) rather than rescanned.
    ``handshake_timeout``: seconds a TCP link may stay pending (not
    :meth:`Link.establish`-ed); ``max_pending`` and ``max_pending_per_address``: pending
    links at once, in all and from one address.
    ``framer``: makes each link's framer instead of the C one of ``protocol`` (a line
    protocol the C core does not frame).
    """

    def __init__(
        self,
        session_factory: SessionFactory,
        *,
        protocol: str,
        max_clients: int = 1,
        max_frame: int | None = None,
        byte_timeout: float = 0.1,
        send_timeout: float = 1.0,
        max_backlog: int = 1 << 20,
        name: str = "server",
        busy_reason: str = BUSY_REASON,
        pace: bool = False,
        output_budget: int | None = None,
        strict_framing: bool = False,
        handshake_timeout: float | None = None,
        max_pending: int | None = None,
        max_pending_per_address: int | None = None,
        framer: Callable[[], Any] | None = None,
    ) -> None:
        if max_clients < 1:
            raise ValueError("max_clients must be >= 1")
        if not (byte_timeout > 0 and send_timeout > 0 and max_backlog > 0):
            raise ValueError("byte_timeout, send_timeout and max_backlog must be > 0")
        if handshake_timeout is not None and not handshake_timeout > 0:
            raise ValueError("handshake_timeout must be > 0")
        for what, v in (("max_pending", max_pending),
                        ("max_pending_per_address", max_pending_per_address)):  # fmt: skip
            if v is not None and v < 1:
                raise ValueError(f"{what} must be >= 1")
        if framer is None:
            Framer(protocol, max_frame)  # validates both now, not in the first link's thread
        self.budget = OutputBudget(output_budget)
        """The output waiting over every link: its cap, total now and peak."""
        self.limits = LinkLimits(
            protocol, max_frame, byte_timeout, send_timeout, max_backlog, pace=pace,
            strict=strict_framing, handshake_timeout=handshake_timeout, budget=self.budget,
            framer=framer,
        )  # fmt: skip
        self.max_clients = max_clients
        self.max_pending, self.max_pending_per_address = max_pending, max_pending_per_address
        self.name, self.busy_reason = name, busy_reason
        self._factory = session_factory
        self._lock = threading.Lock()
        self._links: list[Link] = []
        self._threads: list[threading.Thread] = []
        self._refusing: set[socket.socket] = set()
        self._past = ServerLinkStats()
        self._accepted = self._refused = self._evicted = 0
        self._closed = False
        self._listener: socket.socket | None = None
        self._waker: tuple[socket.socket, socket.socket] | None = None
        self._url: str | None = None
        self._pty_path: str | None = None

    # ---------------------------------------------------------------- public API

    @property
    def url(self) -> str | None:
        """``tcp://host:port`` once :meth:`serve_tcp` ran."""
        return self._url

    @property
    def pty_path(self) -> str | None:
        """The pseudo-terminal's device once :meth:`serve_pty` ran."""
        return self._pty_path

    @property
    def accepted(self) -> int:
        """Links accepted since the start."""
        return self._accepted

    @property
    def refused(self) -> int:
        """Connections refused (limit reached) since the start."""
        return self._refused

    @property
    def evicted(self) -> int:
        """Pending links closed to make room for newer connections, since the start."""
        return self._evicted

    def reap(self, timeout: float = REAP_WAIT_S) -> int:
        """Wait at most ``timeout`` s for the links whose peer has already closed (or that
        were dropped) to end, so their places are free; returns how many ended."""
        with self._lock:
            gone = [link for link in self._links if link.peer_closed()]
        end = time.monotonic() + timeout
        for link in gone:
            link.wait_ended(end - time.monotonic())
        return sum(link.ended for link in gone)

    def links(self) -> list[Link]:
        """The links open now."""
        with self._lock:
            return list(self._links)

    def stats(self) -> ServerLinkStats:
        """Counters summed over every link, past and present."""
        with self._lock:
            total = ServerLinkStats()
            total.add(self._past)
            for link in self._links:
                total.add(link.stats)
        return total

    def serve_tcp(self, host: str = "127.0.0.1", port: int = 0) -> str:
        """Listen on ``host:port`` (0: an ephemeral port); returns ``tcp://host:port``."""
        self._check_unused()
        listener = listen(host, port)
        try:
            self._waker = socket.socketpair()
        except OSError as exc:
            listener.close()
            raise TransportError(f"cannot create the server's wake-up socket: {exc}") from exc
        self._listener = listener
        real_port = listener.getsockname()[1]
        shown = f"[{host}]" if ":" in host else host
        self._url = f"tcp://{shown}:{real_port}"
        self._start(f"{self.name}-accept-{real_port}", self._accept_loop)
        log.info("%s listening on %s", self.name, self._url)
        return self._url

    def serve_pty(self) -> str:
        """Serve one link on a new pseudo-terminal in raw mode; returns its device path."""
        self._check_unused()
        if not hasattr(os, "openpty"):
            raise TransportError("pseudo-terminals are not available on this platform")
        import tty

        master, slave = os.openpty()
        try:
            tty.setraw(slave)
            os.set_blocking(master, False)
            path = os.ttyname(slave)
            link = PtyLink(self.limits, master, slave, path, self._detach)
        except BaseException:
            os.close(master)
            os.close(slave)
            raise
        self._pty_path = path
        with self._lock:
            self._admit(link)
        log.info("%s serving on %s", self.name, path)
        return path

    def close(self, timeout: float = JOIN_TIMEOUT_S) -> None:
        """Drop every link, stop and join every thread (within ``timeout`` s in total; a
        thread that would not stop is logged). Idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            links = list(self._links)
            threads = list(self._threads)
            refusing = list(self._refusing)
        if self._waker is not None:
            self._waker[1].send(b"x")
        for link in links:
            link.close()
        for sock in refusing:
            _shutdown(sock)  # the refusal line was sent or is lost: stop lingering
        deadline = time.monotonic() + timeout
        for t in threads:
            if t is not threading.current_thread():
                t.join(max(0.0, deadline - time.monotonic()))
                if t.is_alive():
                    log.warning("%s: thread %s did not stop within %.1f s", self.name, t.name,
                                timeout)  # fmt: skip
        for sock in (self._listener, *(self._waker or ())):
            if sock is not None:
                sock.close()

    # ---------------------------------------------------------------- internals

    def _check_unused(self) -> None:
        if self._closed:
            raise TransportError(f"{self.name} is closed")
        if self._url is not None or self._pty_path is not None:
            raise TransportError(f"{self.name} already serves {self._url or self._pty_path}")

    def _start(self, name: str, target: Callable[[], None]) -> None:
        t = threading.Thread(target=target, name=name, daemon=True)
        self._threads = [old for old in self._threads if old.is_alive()]
        self._threads.append(t)
        t.start()

    def _admit(self, link: Link) -> None:
        """Make the link's session and start its thread (server lock held)."""
        link.session = self._factory(link)
        self._links.append(link)
        self._accepted += 1
        self._start(f"{self.name}-{link.name}", link._run)

    def _detach(self, link: Link) -> None:
        """Called by a link's thread as it ends: the session hears it under the server lock,
        so a client accepted next never sees the old session still open."""
        with self._lock:
            if link not in self._links:
                return
            self._links.remove(link)
            self._past.add(link.stats)
            session = link.session
            if session is not None:
                session.on_close()
        log.info("%s: %s gone", self.name, link.name)

    def _accept_loop(self) -> None:
        listener, waker = self._listener, self._waker
        assert listener is not None and waker is not None
        while True:
            ready, _, _ = select.select([listener, waker[0]], [], [])
            if waker[0] in ready:
                return
            try:
                sock, addr = listener.accept()
            except OSError as exc:  # the peer gave up before accept, or fds exhausted
                log.debug("%s: accept failed: %s", self.name, exc)
                time.sleep(0.01)
                continue
            self._accept_one(sock, f"tcp {addr[0]}:{addr[1]}", str(addr[0]))

    def _accept_one(self, sock: socket.socket, peer: str, address: str) -> None:
        """Admit a new connection, or refuse it when the server is full. A client that
        closed and reconnects at once finds its old link still in place until that link's
        thread has seen the end of the stream: links whose peer has closed are waited for
        (at most :data:`REAP_WAIT_S`) before anyone is told "busy"."""
        end = time.monotonic() + REAP_WAIT_S
        while True:
            with self._lock:
                if self._closed:
                    sock.close()
                    return
                if len(self._links) < self.max_clients:
                    self._make_pending_room(address)
                    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                    self._admit(TcpLink(self.limits, sock, peer, self._detach, address))
                    break
                gone = [link for link in self._links if link.peer_closed()]
                if not gone or time.monotonic() >= end:
                    self._refuse(sock, peer)
                    return
            for link in gone:  # not under the lock: the link's end takes it
                link.wait_ended(end - time.monotonic())
        log.info("%s: %s connected", self.name, peer)

    def _make_pending_room(self, address: str) -> None:
        """Close pending links so that one more from ``address`` stays within
        ``max_pending_per_address`` and ``max_pending`` (server lock held)."""
        if self.max_pending is None and self.max_pending_per_address is None:
            return
        pending = [link for link in self._links if link.alive and not link.established]
        per_address = self.max_pending_per_address
        same = [link for link in pending if link.address == address]
        if per_address is not None and len(same) >= per_address:
            pending.remove(self._evict(same, f"over {per_address} pending from {address}"))
        if self.max_pending is not None and len(pending) >= self.max_pending:
            self._evict(pending, f"over {self.max_pending} pending connections")

    def _evict(self, links: list[Link], why: str) -> Link:
        """Close the oldest of ``links`` that has sent nothing, else the oldest."""
        idle = [link for link in links if link.idle()]
        victim = min(idle or links, key=lambda link: link.opened)
        log.info("%s: %s closed before its handshake: %s", self.name, victim.name, why)
        self._evicted += 1
        victim.close()
        return victim

    def _refuse(self, sock: socket.socket, peer: str) -> None:
        """Send the refusal line and close (server lock held). The socket lingers in a short
        thread, reading until the client closes, so the line is not lost to a reset."""
        self._refused += 1
        log.warning("%s: %s refused (%s)", self.name, peer, self.busy_reason)
        try:  # a new socket's buffer takes the line at once; sent here, close() cannot race it
            sent = sock.send(refusal_line(self.busy_reason), DONTWAIT)
        except OSError:
            sent = 0  # the peer is gone: nothing to tell
        if len(self._refusing) >= MAX_REFUSING or not sent:
            sock.close()
            return

        def linger() -> None:
            try:
                sock.settimeout(REFUSE_LINGER_S)
                sock.shutdown(socket.SHUT_WR)
                end = time.monotonic() + REFUSE_LINGER_S
                while time.monotonic() < end and sock.recv(4096):
                    pass
            except OSError:
                pass  # timeout or reset: the line was offered, the link closes anyway
            finally:
                with self._lock:
                    self._refusing.discard(sock)
                sock.close()

        self._refusing.add(sock)
        self._start(f"{self.name}-{peer}-refuse", linger)


def _shutdown(sock: socket.socket) -> None:
    try:
        sock.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass  # not connected any more


def listen(host: str, port: int, backlog: int = LISTEN_BACKLOG) -> socket.socket:
    """A listening TCP socket on ``host:port``; a port in use is a clear
    :class:`~robocli.errors.TransportError`."""
    try:
        family, kind, proto, _, addr = socket.getaddrinfo(
            host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE
        )[0]
    except socket.gaierror as exc:
        raise TransportError(f"cannot listen on {host}:{port}: {exc.strerror}") from exc
    sock = socket.socket(family, kind, proto)
    try:
        if os.name == "nt":
            sock.setsockopt(socket.SOL_SOCKET, getattr(socket, "SO_EXCLUSIVEADDRUSE", 0), 1)
        else:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(addr)
        sock.listen(backlog)
    except OSError as exc:
        sock.close()
        if exc.errno in (errno.EADDRINUSE, getattr(errno, "WSAEADDRINUSE", -1)):
            raise TransportError(f"port {port} is in use: is another simulator running?") from exc
        raise TransportError(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from exc
    return sock
