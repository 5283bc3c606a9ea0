"""A hub's serial port over Eclipse Zenoh: :class:`ZenohSerialLine`, the counterpart of
:class:`~robocli.devices.hub.serial.VirtualSerial` for a hub served with ``serve --zenoh``
(the keys: :mod:`robocli.hub_server.frontends.zenoh_serial`).

The user is the one the Zenoh configuration authenticates as (the router's user, whose key
chunk the lab's access control lets through); the hub's token goes in the open request, as
for its settings. When the hub's liveliness token goes, the line says ``"lost"`` and waits
``resume`` seconds for it to come back, then opens the port again (``"resumed"``) or ends
(``"ended"``, every call then raising); it ends at once when the hub reports its port failed.
"""

from __future__ import annotations

import json
import logging
import threading
from collections.abc import Callable
from typing import Any

from robocli.closing import closed_on_error
from robocli.devices.hub.serial import RESUME_S, LineEvents, LineSettings
from robocli.errors import ConnectionLost, DeviceError, InvalidArgument, RobocliError, TimeoutError
from robocli.protocols.ros4mat import MAX_STREAM_CHUNK
from robocli.zenoh.keys import alive_key, check_name, serial_data_key, serial_key
from robocli.zenoh.payload import decode_object
from robocli.zenoh.session import close_session, config_user, import_zenoh, open_session

__all__ = ["ZenohSerialLine"]

log = logging.getLogger("robocli.devices.hub.zenoh_serial")

MAX_REPLY = 64 * 1024


class ZenohSerialLine(LineEvents):
    """The serial ``port`` of the hub named ``hub`` on Zenoh (see the module docstring).
    ``on_data(bytes)`` gets the port's bytes in Zenoh's thread (it must not block)."""

    _log = log

    def __init__(self, session: Any, hub: str, port: str, user: str, settings: LineSettings,
                 token: bytes | None, timeout: float,
                 on_data: Callable[[bytes], None],
                 on_event: Callable[[str, str], None] | None,
                 resume: float = RESUME_S) -> None:  # fmt: skip
        self.session, self.hub, self.port, self.user = session, hub, port, user
        self.settings = settings
        self.timeout = timeout
        self._token = token
        self._on_data, self._on_event = on_data, on_event
        self.resume = resume
        self.resumes = 0  #: times the line came back after the hub went away
        self._error: RobocliError | None = None
        self._lock = threading.Lock()
        self._back = threading.Event()  # the hub's liveliness token came back
        self._down = False  # the hub went away; the line waits for it
        self.bytes_in = self.bytes_out = 0
        self._declared: list[Any] = []

    @classmethod
    def open(
        cls,
        hub: str,
        port: str,
        *,
        zenoh: str | None,
        on_data: Callable[[bytes], None],
        on_event: Callable[[str, str], None] | None = None,
        token: bytes | str | None = None,
        timeout: float = 5.0,
        resume: float = RESUME_S,
        baudrate: int = 9600,
        bytesize: int = 8,
        parity: str = "N",
        stopbits: float = 1,
    ) -> ZenohSerialLine:
        """Open ``port`` of the hub ``hub`` through the Zenoh configuration ``zenoh`` (its
        user streams it). :class:`DeviceError` when the hub refuses, :class:`TimeoutError`
        when no hub of that name answers."""
        check_name(hub, "hub name")
        user = config_user(zenoh)
        if user is None:
            raise InvalidArgument("a serial port over Zenoh needs a configuration with the "
                                  "router's user (transport/auth/usrpwd)")  # fmt: skip
        settings = LineSettings(baudrate, bytesize, parity, stopbits)
        secret = token.encode() if isinstance(token, str) else token
        session = open_session(zenoh, "client")
        line = cls(session, hub, port, user, settings, secret, timeout, on_data, on_event,
                   resume)  # fmt: skip
        with closed_on_error(line):
            line._start()
        return line

    def _start(self) -> None:
        z, s = import_zenoh(), self.session
        self._declared += [
            s.liveliness().declare_token(serial_key(self.hub, self.user, "serial-alive")),
            s.declare_subscriber(serial_data_key(self.hub, self.port), self._on_bytes),
            s.declare_subscriber(
                serial_key(self.hub, self.user, "serial-error"), self._on_error
            ),  # fmt: skip
            s.liveliness().declare_subscriber(alive_key(self.hub, "hub"), self._on_hub),
        ]
        self._writer = s.declare_publisher(
            serial_key(self.hub, self.user, "serial-write"),
            congestion_control=z.CongestionControl.BLOCK, express=True,
        )  # fmt: skip
        self._declared.append(self._writer)
        self._open()

    def _open(self) -> None:
        request = {**self.settings, "port": self.port}
        if self._token is not None:
            request["token"] = self._token.decode()
        key = serial_key(self.hub, self.user, "serial-open")
        for reply in self.session.get(key, payload=json.dumps(request), timeout=self.timeout):
            if reply.ok is not None:
                return
            raw = reply.err.payload.to_bytes() if reply.err is not None else b""
            text = str(decode_object(raw or b"{}", "serial-open error", MAX_REPLY).get("error"))
            raise DeviceError(f"hub {self.hub} refused serial-open: {text}")
        raise TimeoutError(f"no hub {self.hub!r} answered serial-open on Zenoh within "
                           f"{self.timeout:g} s")  # fmt: skip

    # ------------------------------------------------------------------ bytes

    def _on_bytes(self, sample: Any) -> None:
        data = sample.payload.to_bytes()
        self.bytes_in += len(data)
        self._on_data(data)

    def _on_error(self, sample: Any) -> None:
        try:
            text = decode_object(sample.payload.to_bytes(), "serial-error", MAX_REPLY)
            self._end(DeviceError(str(text.get("error"))))
        except RobocliError as exc:
            self._end(exc)

    def _on_hub(self, sample: Any) -> None:
        if sample.kind == import_zenoh().SampleKind.PUT:
            self._back.set()
            return
        with self._lock:
            if self._down or self._error is not None:
                return
            self._down = True
            self._back.clear()
        self._event("lost", f"hub {self.hub} left Zenoh; {self.port} waiting up to "
                  f"{self.resume:g} s for it")  # fmt: skip
        threading.Thread(target=self._await_hub, name="zenoh-serial-resume", daemon=True).start()

    def _await_hub(self) -> None:
        """The hub went away: open the port again when it comes back, or end the line."""
        if not self._back.wait(self.resume) or self._error is not None:
            self._end(ConnectionLost(f"hub {self.hub} did not come back in {self.resume:g} s"))
            return
        try:
            self._open()
        except RobocliError as exc:
            self._end(exc)
            return
        self._down = False
        self.resumes += 1
        self._event("resumed", f"hub back: {self.port} on {self.hub} resumed")

    def _end(self, exc: RobocliError) -> None:
        with self._lock:
            if self._error is not None:
                return
            self._error = exc
        self._event("ended", str(exc))

    def write(self, data: bytes | bytearray | memoryview) -> int:
        """Put ``data`` for the hub's port, in pieces of at most ``MAX_STREAM_CHUNK``."""
        if self._error is not None:
            raise self._error
        if self._down:
            raise ConnectionLost(f"hub {self.hub} away; {self.port} waiting for it")
        raw = bytes(data)
        for i in range(0, len(raw), MAX_STREAM_CHUNK):
            self._writer.put(raw[i : i + MAX_STREAM_CHUNK])
        self.bytes_out += len(raw)
        return len(raw)

    def configure(self, **settings: Any) -> None:
        """New line settings for the hub's port (another serial-open)."""
        new = LineSettings(**{**self.settings, **settings})
        if new != self.settings:
            self.settings = new
            self._open()

    @property
    def connected(self) -> bool:
        return self._error is None and not self._down

    @property
    def ended(self) -> RobocliError | None:
        return self._error

    def close(self) -> None:
        """Undeclare (the hub ends the stream when the liveliness token goes) and close the
        session. Idempotent."""
        if self._error is None:
            self._error = ConnectionLost(f"{self.port}: the serial line is closed")
        self._back.set()  # a waiting resume ends now
        for entity in self._declared:
            try:
                entity.undeclare()
            except Exception as exc:
                log.debug("undeclare: %s", exc)
        self._declared.clear()
        if self.session is not None:
            close_session(self.session)
            self.session = None
