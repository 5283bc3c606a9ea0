"""A serial port of the hub as a local byte stream: :class:`VirtualSerial`.

>>> with VirtualSerial.open("127.0.0.1", "/dev/ttyUSB0", baudrate=115200) as line:  # doctest: +SKIP
...     line.write(bytes([128, 131]))        # the Create's START, SAFE
...     reply = line.read(80, timeout=1.0)

It speaks robocli's streaming extension of ros4mat (:mod:`robocli.protocols.ros4mat.stream`):
SERIAL_OPEN, then the bytes both ways as they come (a reader thread takes the hub's pushed
SERIAL_DATA), each write with a deadline. The hub's token guards it as it guards
``SERIAL_CMD``: give ``token`` (the content of the hub's ``--token-file``).

**The hub restarting.** When the link drops, the line says so (``on_event("lost", ...)``),
connects again every :data:`RETRY_S` for ``resume`` seconds with the same settings, and says
``"resumed"``; past that it says ``"ended"`` and every call raises
:class:`~robocli.errors.ConnectionLost`. Bytes the hub's port sent during the outage are not
seen (a serial line does not keep them either); writes during it raise.

:mod:`robocli.devices.hub.relay` puts one on a local pseudo-terminal, and
:mod:`robocli.devices.hub.urlhandler` makes it a pyserial URL (``robocli://``).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from robocli.closing import Closing, closed_on_error
from robocli.devices.hub.decode import body_of
from robocli.devices.hub.link import (
    handshake,
    header_only,
    open_hub,
    open_session,
    parse_hub,
    request,
    token_bytes,
)
from robocli.devices.session import Session
from robocli.errors import ConnectionLost, DeviceError, InvalidArgument, RobocliError
from robocli.protocols.ros4mat import (
    MAX_STREAM_CHUNK,
    PARITIES,
    MsgType,
    encode_request,
    write_deadline,
)

__all__ = ["MAX_BUFFER", "RESUME_S", "RETRY_S", "LineSettings", "VirtualSerial"]

log = logging.getLogger("robocli.devices.hub.serial")

MAX_BUFFER = 1 << 20
"""Bytes from the hub kept for :meth:`VirtualSerial.read` (the oldest go beyond, counted in
:attr:`VirtualSerial.overflowed`); with ``on_data`` nothing is kept."""
RESUME_S = 30.0  #: how long a lost line tries to connect again by default
RETRY_S = 0.5  #: between two attempts
CLOSE_WAIT_S = 2.0  #: the most close() waits for the hub to end the stream
_STOP_TENTHS = {1: 10, 1.5: 15, 2: 20}


class LineSettings(dict[str, Any]):
    """pyserial's names: ``baudrate``, ``bytesize``, ``parity`` (N E O M S), ``stopbits``
    (1, 1.5, 2); checked on creation (:class:`InvalidArgument`)."""

    def __init__(self, baudrate: int = 9600, bytesize: int = 8, parity: str = "N",
                 stopbits: float = 1) -> None:  # fmt: skip
        if not isinstance(baudrate, int) or not 1 <= baudrate <= 4_000_000:
            raise InvalidArgument(f"baudrate {baudrate!r}: 1..4000000")
        if bytesize not in (5, 6, 7, 8):
            raise InvalidArgument(f"bytesize {bytesize!r}: 5, 6, 7 or 8")
        if not isinstance(parity, str) or len(parity) != 1 or parity not in PARITIES:
            raise InvalidArgument(f"parity {parity!r}: one of {', '.join(PARITIES)}")
        if stopbits not in _STOP_TENTHS:
            raise InvalidArgument(f"stopbits {stopbits!r}: 1, 1.5 or 2")
        super().__init__(baudrate=baudrate, bytesize=bytesize, parity=parity,
                         stopbits=stopbits)  # fmt: skip

    def body(self, port: str) -> dict[str, Any]:
        """The SERIAL_OPEN body for ``port``."""
        return {"speed": self["baudrate"], "byte_size": self["bytesize"],
                "parity": self["parity"], "stop_bits": _STOP_TENTHS[self["stopbits"]],
                "port": port}  # fmt: skip


class LineEvents(Closing):
    """What a serial line through the hub tells of its link (``"lost"``, ``"resumed"``,
    ``"ended"``): logged on :attr:`_log` and handed to ``on_event(kind, text)``."""

    port: str
    _on_event: Callable[[str, str], None] | None
    _log = log

    def _event(self, kind: str, text: str) -> None:
        self._log.info("%s: %s: %s", self.port, kind, text)
        if self._on_event is not None:
            self._on_event(kind, text)


class VirtualSerial(LineEvents):
    """The hub's serial ``port`` streamed to this machine (see the module docstring).

    ``on_data(bytes)``, if given, gets the bytes from the hub in the reader's thread (it
    must not block); otherwise :meth:`read` takes them from a buffer of :data:`MAX_BUFFER`.
    ``on_event(kind, text)`` hears ``"lost"``, ``"resumed"`` and ``"ended"``.
    """

    def __init__(
        self,
        hub: str,
        port: str,
        settings: LineSettings,
        *,
        token: bytes | str | None = None,
        timeout: float = 5.0,
        resume: float = RESUME_S,
        on_data: Callable[[bytes], None] | None = None,
        on_event: Callable[[str, str], None] | None = None,
    ) -> None:
        self.host, self.hub_port = parse_hub(hub)
        self.port = port
        self.settings = settings
        self.timeout = timeout
        self.resume = resume
        self._token = token_bytes(token)
        self._on_data = on_data
        self._on_event = on_event
        self._buffer = bytearray()
        self._cond = threading.Condition()
        self._session: Session | None = None
        self._client_id = 0
        self._error: RobocliError | None = None  # the line ended with it
        self._closed = False
        self.overflowed = 0  #: bytes from the hub dropped because nobody read them
        self.bytes_in = 0  #: bytes received from the hub's port
        self.bytes_out = 0  #: bytes sent to it
        self.resumes = 0  #: times the line came back after the hub went away
        self._watch: threading.Thread | None = None

    # ------------------------------------------------------------------ opening

    @classmethod
    def open(
        cls,
        hub: str,
        port: str,
        *,
        baudrate: int = 9600,
        bytesize: int = 8,
        parity: str = "N",
        stopbits: float = 1,
        **kwargs: Any,
    ) -> VirtualSerial:
        """Connect to ``hub`` (``HOST[:PORT]``) and open its serial ``port``. Raises
        :class:`~robocli.errors.TransportError` when no hub listens, :class:`DeviceError`
        when it refuses (no token, a port not on its allow-list, busy, cannot open)."""
        line = cls(hub, port, LineSettings(baudrate, bytesize, parity, stopbits), **kwargs)
        line._session = line._connect()
        line._watch = threading.Thread(target=line._supervise, name="vserial-watch",
                                       daemon=True)  # fmt: skip
        line._watch.start()
        return line

    def _connect(self) -> Session:
        """A new link: CONNECT (with the token), the reader, SERIAL_OPEN."""
        session = open_session(open_hub(self.host, self.hub_port, self.timeout))
        header, _, _ = handshake(session, client_id=0, compress=False, token=self._token,
                                 clock=time.time, timeout=self.timeout)  # fmt: skip
        self._client_id = int(header[2])
        session.on_frame = self._on_frame
        session.start()
        with closed_on_error(session):
            self._open_on(session)
        return session

    def _open_on(self, session: Session) -> None:
        packet = encode_request(MsgType.SERIAL_OPEN, self.settings.body(self.port),
                                client_id=self._client_id)  # fmt: skip
        body_of(request(session, packet, MsgType.SERIAL_OPEN_ACK, self.timeout))

    def configure(self, **settings: Any) -> None:
        """New line settings (``baudrate``, ``bytesize``, ``parity``, ``stopbits``) for the
        hub's port, applied before any byte written after this returns."""
        new = LineSettings(**{**self.settings, **settings})
        if new == self.settings:
            return
        self.settings = new
        self._open_on(self._live())
        log.info("%s: line settings %s", self.port, dict(new))

    # ------------------------------------------------------------------ bytes

    def _on_frame(self, frame: bytes, _t: float) -> None:
        kind, error = frame[0], frame[1]
        if kind == MsgType.SERIAL_DATA and not error:
            data = bytes(body_of(frame)[1])
            self.bytes_in += len(data)
            if self._on_data is not None:
                self._on_data(data)
                return
            with self._cond:
                self._buffer += data
                over = len(self._buffer) - MAX_BUFFER
                if over > 0:
                    del self._buffer[:over]
                    self.overflowed += over
                self._cond.notify_all()
        elif error and kind in (MsgType.SERIAL_DATA, MsgType.SERIAL_WRITE, MsgType.SERIAL_CLOSE):
            try:
                body_of(frame)
            except DeviceError as exc:  # the hub's text: the port failed, a write refused
                self._end(exc)

    def write(self, data: bytes | bytearray | memoryview) -> int:
        """Send ``data`` to the hub's port (in pieces of at most
        :data:`~robocli.protocols.ros4mat.MAX_STREAM_CHUNK`), each within the hub's deadline for
        it plus a second (:func:`~robocli.protocols.ros4mat.write_deadline`); returns how many
        bytes went."""
        session = self._live()
        raw = bytes(data)
        # the hub takes a write once it wrote what came before, at the line's rate
        deadline = write_deadline(self.settings, MAX_STREAM_CHUNK) + 1.0
        for i in range(0, len(raw), MAX_STREAM_CHUNK):
            piece = raw[i : i + MAX_STREAM_CHUNK]
            packet = encode_request(MsgType.SERIAL_WRITE, piece, client_id=self._client_id)
            session.send(packet, deadline)
            self.bytes_out += len(piece)
        return len(raw)

    def read(self, size: int = 1, timeout: float | None = None) -> bytes:
        """Up to ``size`` bytes from the hub's port: what is there, or the first that come
        within ``timeout`` s (None: wait until some come or the line ends); b"" after a
        timeout."""
        end = None if timeout is None else time.monotonic() + timeout
        with self._cond:
            while not self._buffer:
                if self._error is not None:
                    raise self._error
                left = None if end is None else end - time.monotonic()
                if left is not None and left <= 0:
                    return b""
                self._cond.wait(0.25 if left is None else min(left, 0.25))
            data = bytes(self._buffer[:size])
            del self._buffer[:size]
            return data

    @property
    def in_waiting(self) -> int:
        """Bytes received and not read yet."""
        return len(self._buffer)

    def reset_input(self) -> None:
        """Forget the bytes received and not read."""
        with self._cond:
            self._buffer.clear()

    # ------------------------------------------------------------------ the link's life

    @property
    def connected(self) -> bool:
        """Whether the link to the hub is up now."""
        s = self._session
        return s is not None and s.alive

    @property
    def ended(self) -> RobocliError | None:
        """Why the line ended (None while it lives)."""
        return self._error

    def _live(self) -> Session:
        if self._error is not None:
            raise self._error
        s = self._session
        if s is None or not s.alive:
            raise ConnectionLost(f"{self.host}:{self.hub_port}: link to the hub down; "
                                 "reconnecting")  # fmt: skip
        return s

    def _end(self, exc: RobocliError) -> None:
        with self._cond:
            if self._error is None:
                self._error = exc
            self._cond.notify_all()

    def _supervise(self) -> None:
        """Watch the link; when it drops, connect again for ``resume`` s."""
        while not self._closed and self._error is None:
            session = self._session
            assert session is not None
            with session.cond:
                if session.alive and not self._closed:
                    session.cond.wait(0.5)
            if self._closed or self._error is not None or session.alive:
                continue
            why = str(session.error or "closed")
            session.close()
            self._event("lost", f"hub lost ({why}); {self.port} reconnecting for up to "
                        f"{self.resume:g} s")  # fmt: skip
            deadline = time.monotonic() + self.resume
            while not self._closed:
                try:
                    fresh = self._connect()
                except DeviceError as exc:  # the new hub refuses: no use retrying
                    self._event("ended", str(exc))
                    self._end(exc)
                    return
                except (RobocliError, OSError) as exc:
                    if time.monotonic() + RETRY_S > deadline:
                        self._event("ended", f"no hub for {self.resume:g} s ({exc})")
                        where = f"{self.host}:{self.hub_port}"
                        self._end(
                            ConnectionLost(
                                f"{where}: the hub did not come back in {self.resume:g} s"
                            )
                        )
                        return
                    time.sleep(RETRY_S)  # the retry period, not a wait for an event
                    continue
                self._session = fresh  # close() closes it if it came after close began
                if self._closed:
                    return
                self.resumes += 1
                self._event("resumed", f"hub back: {self.port} on {self.host}:{self.hub_port} "
                            "resumed")  # fmt: skip
                break

    def close(self) -> None:
        """Close the stream (SERIAL_CLOSE and QUIT), the link and the watcher (bounded).
        Idempotent."""
        self._closed = True
        self._end(ConnectionLost(f"{self.port}: the virtual serial port is closed"))
        session = self._session
        if session is not None:
            with session.cond:  # wakes the watcher
                session.cond.notify_all()
        if self._watch is not None and self._watch is not threading.current_thread():
            self._watch.join(self.timeout + RETRY_S)  # it may be connecting: then it stops
        session = self._session  # the watcher's last link, if it made one
        if session is not None:
            goodbye: tuple[bytes, ...] = (header_only(MsgType.SERIAL_CLOSE, self._client_id),
                                          header_only(MsgType.QUIT, self._client_id))  # fmt: skip
            try:
                session.send_many(goodbye, CLOSE_WAIT_S)
                goodbye = ()
                # the hub ends the stream, then closes the connection on QUIT: once it has,
                # the port is free for the next client (close() returning means just that)
                with session.cond:
                    session.cond.wait_for(lambda: not session.alive, CLOSE_WAIT_S)
            except (RobocliError, OSError):
                pass  # the link is gone already: so is the stream, with the connection
            session.close(goodbye)

    def __repr__(self) -> str:
        return f"VirtualSerial({self.host}:{self.hub_port} {self.port} {dict(self.settings)})"
