"""The hub's serial ports streamed over Zenoh, beside the ros4mat stream (robocli's
extension), under the same rules: the hub's token, its allow-list, one stream per port,
bounded writes with a deadline.

Who streams is the user the key names, ``robocli/<hub>/@control/<user>/...``: under the lab's
access control (:mod:`robocli.zenoh.acl`) the router lets a user put and query only under its
own name, so the holder is the user the router authenticated, never a name a payload claims.

* ``serial-open`` (query, JSON ``{"port", "baudrate", "bytesize", "parity", "stopbits",
  "token"}``): opens the port for that user (again: new settings); the reply names the data
  key. Every query gets a reply, an error one when refused.
* ``serial-write`` (put, the bytes, at most
  :data:`~robocli.protocols.ros4mat.MAX_STREAM_CHUNK`): written to that user's stream within
  its deadline (in Zenoh's callback thread: a line that does not take them holds it that
  long at most).
* ``serial-alive`` (liveliness token): the stream ends when the user's token goes.
* ``serial-error`` (put by the hub): why the user's stream ended (JSON ``{"error": ...}``).
* ``robocli/<hub>/serial-<port>``: the bytes the port sent, put as they come.
"""

from __future__ import annotations

import hmac
import json
import logging
import threading
from collections.abc import Mapping
from functools import partial
from typing import Any

from robocli.errors import DeviceError, ProtocolError, RobocliError
from robocli.hub_server.serial import SerialStream, line_settings
from robocli.hub_server.sources import SerialPorts
from robocli.protocols.ros4mat import MAX_STREAM_CHUNK
from robocli.zenoh.keys import serial_data_key, serial_holder, serial_key
from robocli.zenoh.payload import decode_object
from robocli.zenoh.session import import_zenoh, undeclare

__all__ = ["ZenohSerial"]

log = logging.getLogger("robocli.hub_server")

MAX_OPEN_BYTES = 4096  #: the largest serial-open payload taken


class ZenohSerial:
    """Serves ``ports`` (the hub's allow-list) on the Zenoh ``session`` under ``name``."""

    def __init__(self, session: Any, name: str, ports: SerialPorts, token: bytes | None) -> None:
        self.session, self.name, self.ports = session, name, ports
        self._token = token
        self._streams: dict[str, SerialStream] = {}  # user -> its stream
        self._publishers: dict[str, Any] = {}  # user -> the publisher of its port's bytes
        self._lock = threading.Lock()
        self.refused = 0  #: opens refused
        self.dropped_writes = 0  #: writes from a user with no stream, or too long
        s = session
        self._declared = [
            s.declare_queryable(serial_key(name, None, "serial-open"), self._on_open),
            s.declare_subscriber(serial_key(name, None, "serial-write"), self._on_write),
            s.liveliness().declare_subscriber(
                serial_key(name, None, "serial-alive"), self._on_alive
            ),
        ]

    # ------------------------------------------------------------------ opening

    def open(self, user: str, request: Mapping[str, Any]) -> dict[str, Any]:
        """Open (or re-set) ``user``'s stream as ``request`` asks; what the reply says.
        :class:`DeviceError` when refused."""
        if self._token is not None:
            given = request.get("token")
            if not isinstance(given, str) or not hmac.compare_digest(given.encode(), self._token):
                raise DeviceError("unauthorized: serial-open needs the hub's token")
        port = request.get("port")
        if not isinstance(port, str):
            raise DeviceError("serial-open: 'port' must be the hub's port name")
        try:
            stop = float(request.get("stopbits", 1))
            settings = line_settings({
                "speed": int(request.get("baudrate", 9600)),
                "byte_size": int(request.get("bytesize", 8)),
                "parity": str(request.get("parity", "N")), "stop_bits": round(stop * 10),
            })  # fmt: skip
        except (TypeError, ValueError) as exc:
            raise DeviceError(f"serial-open: {exc}") from None
        key = serial_data_key(self.name, port)
        with self._lock:
            stream = self._streams.get(user)
            if stream is not None and stream.name != port:
                raise DeviceError(f"{user} streams {stream.name!r}: close it first")
            if stream is not None:
                stream.apply(settings)
            else:
                publisher = self.session.declare_publisher(key)
                try:
                    stream = SerialStream(
                        self.ports, port, settings, partial(self._push, publisher),
                        partial(self._failed, user),
                    )  # fmt: skip
                except BaseException:
                    undeclare(publisher)
                    raise
                self._streams[user], self._publishers[user] = stream, publisher
        return {"port": port, "key": key, "settings": settings}

    @staticmethod
    def _push(publisher: Any, data: bytes) -> bool:
        publisher.put(data)
        return True

    def _failed(self, user: str, why: str) -> None:
        """The port failed under ``user``'s stream (the stream's reader thread)."""
        try:
            self.session.put(serial_key(self.name, user, "serial-error"),
                             json.dumps({"error": why}))  # fmt: skip
        except Exception as exc:
            log.debug("zenoh serial-error: %s", exc)
        self.end(user)

    def end(self, user: str) -> None:
        """End ``user``'s stream, if any (its port given back)."""
        with self._lock:
            stream = self._streams.pop(user, None)
            publisher = self._publishers.pop(user, None)
        if stream is not None:
            stream.close()
        if publisher is not None:
            undeclare(publisher)

    # ------------------------------------------------------------------ zenoh callbacks

    def _on_open(self, query: Any) -> None:
        try:
            user = serial_holder(query.key_expr, self.name, "serial-open")
            try:
                if user is None:
                    raise DeviceError("not a serial-open key")
                payload = query.payload
                raw = payload.to_bytes() if payload is not None else b""
                try:
                    request = decode_object(raw or b"{}", "serial-open", MAX_OPEN_BYTES)
                except ProtocolError as exc:
                    raise DeviceError(str(exc)) from None
                answer = self.open(user, request)
            except RobocliError as exc:
                self.refused += 1
                query.reply_err(json.dumps({"error": str(exc)}))
                return
            query.reply(query.key_expr, json.dumps(answer),
                        encoding=import_zenoh().Encoding.APPLICATION_JSON)  # fmt: skip
        except Exception as exc:
            log.warning("zenoh serial-open: %s", exc)

    def _on_write(self, sample: Any) -> None:
        try:
            user = serial_holder(sample.key_expr, self.name, "serial-write")
            stream = self._streams.get(user) if user is not None else None
            data = sample.payload.to_bytes()
            if stream is None or not 0 < len(data) <= MAX_STREAM_CHUNK:
                self.dropped_writes += 1
                return
            try:
                stream.write(data)
            except RobocliError as exc:
                assert user is not None
                self._failed(user, str(exc))
        except Exception as exc:
            log.warning("zenoh serial-write: %s", exc)

    def _on_alive(self, sample: Any) -> None:
        try:
            user = serial_holder(sample.key_expr, self.name, "serial-alive")
            if user is not None and sample.kind != import_zenoh().SampleKind.PUT:
                self.end(user)  # its token went: the user left
        except Exception as exc:
            log.warning("zenoh serial-alive: %s", exc)

    def close(self) -> None:
        """Undeclare everything and end every stream. Idempotent."""
        for entity in self._declared:
            undeclare(entity)
        self._declared.clear()
        for user in list(self._streams):
            self.end(user)
