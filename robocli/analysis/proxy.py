"""A transparent TCP proxy that records every message of the sessions it relays.

``dump hub`` and ``dump arm --listen`` are built on it: a client connects to the proxy
instead of the device (a hub, one port of an ABB controller, which takes one client per port:
the proxy lets a dump see another program's session), the bytes pass through unchanged both
ways, and each complete frame, cut by a :class:`~robocli.core.Framer` of the protocol, is
handed to ``on_message`` before it is passed on (so a reply is never shown before its
request).

Bounded: at most ``max_clients`` sessions at once (a client over that is closed after
waiting at most ``_SLOT_WAIT_S`` for a session to end: its client may have closed already),
one read of 64 KiB per relay step, a frame no larger than the framer's ``max_frame``, and a
deadline of ``_IO_TIMEOUT_S`` on every write (a side that stops reading ends its session).
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from robocli.core import Framer
from robocli.errors import InvalidArgument, TransportError

__all__ = ["Describe", "Message", "RecordingProxy", "check_upstream", "listen"]

#: the deadline for a write (and how often a quiet read checks for close)
_IO_TIMEOUT_S = 1.0
_READ = 65536
_SLOT_WAIT_S = 2.0
"""How long a client over ``max_clients`` waits for a session whose client has closed (its
relaying thread may not have seen the end yet) before it is refused."""

log = logging.getLogger("robocli.analysis.proxy")

#: ``describe(frame) -> (name, fields)``: how a protocol names and decodes one whole frame.
Describe = Callable[[bytes], tuple[str, dict[str, Any]]]


@dataclass
class Message:
    """One message seen by a :class:`RecordingProxy`."""

    t: float  #: seconds since the proxy was made (monotonic)
    direction: str  #: "c2s" (client to device) or "s2c"
    name: str
    frame: bytes
    fields: dict[str, Any] = field(default_factory=dict)


class RecordingProxy:
    """Relay TCP sessions to ``upstream`` and show each ``framer`` frame to ``on_message``.

    ``framer``: a :data:`robocli.core.PROTOCOLS` name (``"ros4mat"``, ``"sm-le"``...), with
    ``max_frame`` (its default when None). ``describe`` names and decodes a frame for the
    :class:`Message` (None: the name is empty, the caller decodes ``Message.frame``).
    ``on_message`` is called from the relaying threads, one call at a time; its exceptions
    are the caller's (they end that session). Use :meth:`start`, then :meth:`close` (or
    ``with``); clients connect to :attr:`port` on ``bind``.
    """

    def __init__(self, upstream: tuple[str, int], on_message: Callable[[Message], None], *,
                 framer: str, describe: Describe | None = None, max_frame: int | None = None,
                 bind: str = "127.0.0.1", port: int = 0, max_clients: int = 8,
                 name: str = "proxy") -> None:  # fmt: skip
        Framer(framer, max_frame)  # an unknown protocol or a bad size is refused here
        self.upstream, self.on_message = upstream, on_message
        self._framer, self._max_frame, self._describe = framer, max_frame, describe
        self._lock = threading.Lock()
        self._slots = threading.Condition(self._lock)  # notified when a session ends
        self._listener = listen(bind, port)
        self._listener.settimeout(0.25)
        self.port: int = self._listener.getsockname()[1]
        self._closing = threading.Event()
        self._idle = threading.Condition()
        self._in_flight = 0
        self._socks: list[socket.socket] = []
        self._max = max_clients
        self._start = time.monotonic()
        #: why the last client could not be relayed (``upstream`` refused or unreachable; the
        #: client was closed), or None
        self.upstream_error: OSError | None = None
        self._thread = threading.Thread(target=self._accept, name=name, daemon=True)

    def start(self) -> RecordingProxy:
        """Start accepting clients; returns self."""
        self._thread.start()
        return self

    def _accept(self) -> None:
        while not self._closing.is_set():
            try:
                client, _ = self._listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            try:
                device = socket.create_connection(self.upstream, timeout=5.0)
            except OSError as exc:
                self.upstream_error = exc
                client.close()
                continue
            for s in (client, device):
                # a deadline on every write; a quiet read only looks at the closing flag again
                s.settimeout(_IO_TIMEOUT_S)
                s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            with self._lock:
                if len(self._socks) >= 2 * self._max and not self._slot_freed():
                    log.warning("%s: %d sessions relayed already; a client refused",
                                self._thread.name, self._max)  # fmt: skip
                    client.close()
                    device.close()
                    continue
                self._socks += [client, device]
            for src, dst, way in ((client, device, "c2s"), (device, client, "s2c")):
                threading.Thread(target=self._pump, args=(src, dst, way), daemon=True,
                                 name=f"{self._thread.name}-{way}").start()  # fmt: skip

    def _slot_freed(self) -> bool:
        """All slots are taken (``_lock`` held): wait, at most ``_SLOT_WAIT_S``, for a
        session to end (a client that closed, whose end its relaying thread has not seen
        yet). Whether a slot is free."""
        self._slots.wait_for(lambda: len(self._socks) < 2 * self._max or self._closing.is_set(),
                             _SLOT_WAIT_S)  # fmt: skip
        return len(self._socks) < 2 * self._max and not self._closing.is_set()

    def _pump(self, src: socket.socket, dst: socket.socket, direction: str) -> None:
        """Relay one direction of one session, showing each message before it is passed on.
        A side that stops reading for ``_IO_TIMEOUT_S`` ends the session."""
        framer = Framer(self._framer, self._max_frame)
        describe = self._describe
        try:
            while not self._closing.is_set():
                try:
                    data = src.recv(_READ)
                except TimeoutError:
                    continue  # nothing to relay yet
                if not data:
                    break
                now = time.monotonic() - self._start
                with self._idle:
                    self._in_flight += 1
                try:
                    for frame in framer.feed(data):
                        name, fields = describe(frame) if describe is not None else ("", {})
                        with self._lock:
                            self.on_message(Message(now, direction, name, frame, fields))
                    dst.sendall(data)  # TimeoutError (an OSError): that side stopped reading
                finally:
                    with self._idle:
                        self._in_flight -= 1
                        self._idle.notify_all()
        except OSError:
            pass
        finally:
            # closing: the other way may still be relaying bytes it read (a reply to the last
            # request); :meth:`close` cuts every session once those are through. Otherwise
            # the session ended (a side closed or failed): cut both ways now.
            if not self._closing.is_set():
                self._end(src, dst)

    def _end(self, src: socket.socket, dst: socket.socket) -> None:
        for s in (src, dst):
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)
        with self._lock:  # the session's slot is free again (the other pump may be first)
            for s in (src, dst):
                if s in self._socks:
                    self._socks.remove(s)
                    s.close()
            self._slots.notify_all()

    def close(self, grace: float = 1.0) -> None:
        """Stop accepting, let bytes already read reach their side (``grace`` s at most),
        then cut every proxied session. Idempotent."""
        self._closing.set()
        with self._idle:
            self._idle.wait_for(lambda: self._in_flight == 0, grace)
        self._listener.close()
        with self._lock:
            socks, self._socks = self._socks, []
            self._slots.notify_all()  # a client waiting for a slot gets none
        for s in socks:
            with contextlib.suppress(OSError):
                s.shutdown(socket.SHUT_RDWR)
            s.close()
        if self._thread.is_alive():
            self._thread.join(1.0)

    def __enter__(self) -> RecordingProxy:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def listen(bind: str, port: int) -> socket.socket:
    """A listening TCP socket on ``bind:port``. An address that does not resolve or is not
    this machine's raises :class:`InvalidArgument` (a usage error); a port in use, or one
    this process may not take, :class:`TransportError`."""
    if not 0 <= port < 65536:
        raise InvalidArgument(f"listen: port {port} out of range 0..65535")
    try:
        family, kind, proto, _, addr = socket.getaddrinfo(
            bind, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE
        )[0]
    except (socket.gaierror, UnicodeError) as exc:
        why = exc.strerror if isinstance(exc, socket.gaierror) else "not a host name"
        raise InvalidArgument(
            f"listen: cannot listen on {bind!r}: {why} (give an address of this machine, "
            "e.g. 127.0.0.1)"
        ) from None
    sock = socket.socket(family, kind, proto)
    try:
        if os.name != "nt":  # as socket.create_server: a restarted dump rebinds at once
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(addr)
        sock.listen()
    except OSError as exc:
        sock.close()
        if exc.errno in (errno.EADDRINUSE, getattr(errno, "WSAEADDRINUSE", -1)):
            raise TransportError(
                f"port {port} is in use on {bind}: is another dump or server running?"
            ) from None
        if exc.errno in (errno.EADDRNOTAVAIL, getattr(errno, "WSAEADDRNOTAVAIL", -1)):
            raise InvalidArgument(
                f"listen: {bind} is not an address of this machine ({exc.strerror})"
            ) from None
        raise TransportError(f"cannot listen on {bind}:{port}: {exc.strerror or exc}") from None
    return sock


def check_upstream(
    host: str, port: int, timeout: float = 2.0, what: str = "device", hint: str = ""
) -> None:
    """Raise :class:`TransportError` (``no {what} at host:port (reason); {hint}``) when
    nothing listens there (a connection opened and closed at once)."""
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except OSError as exc:
        why = exc.strerror or str(exc) or type(exc).__name__
        why = why[:1].lower() + why[1:]  # as the transports say it: "connection refused"
        tail = f"; {hint}" if hint else ""
        raise TransportError(f"no {what} at {host}:{port} ({why}){tail}") from None
