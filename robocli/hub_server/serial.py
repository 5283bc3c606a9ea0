"""A serial port of the hub streamed to one client: robocli's extension of ros4mat
(:mod:`robocli.protocols.ros4mat.stream`).

:class:`SerialStream` holds one port of the allow-list alone (claimed from
:class:`~robocli.hub_server.sources.SerialPorts`, so ``SERIAL_CMD`` cannot interleave with it) and
has one thread reading it, which pushes every byte that comes through ``push`` (the
connection's bounded output: a client that stops reading is dropped). Writes run in the
connection's thread with a deadline sized to the line's rate; a port that fails ends the
stream through ``on_fail``.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable, Mapping
from typing import Any

from robocli.errors import DeviceError, InvalidArgument
from robocli.hub_server.sources import SerialPorts
from robocli.hub_server.sources.real import PORT_ERRORS
from robocli.protocols.ros4mat import MAX_STREAM_CHUNK, PARITIES, STOP_BITS, write_deadline

__all__ = ["READ_POLL_S", "SerialStream", "line_settings"]

log = logging.getLogger("robocli.hub_server.serial")

READ_POLL_S = 0.05  #: the reader looks at its stop flag this often when the line is quiet
MAX_BAUD = 4_000_000
JOIN_S = 2.0


def line_settings(body: Mapping[str, Any]) -> dict[str, Any]:
    """pyserial settings of a decoded SERIAL_OPEN body; :class:`InvalidArgument` naming the
    field that no serial line can take."""
    speed, size = int(body["speed"]), int(body["byte_size"])
    parity, stop = str(body["parity"]), int(body["stop_bits"])
    if not 1 <= speed <= MAX_BAUD:
        raise InvalidArgument(f"serial speed {speed} outside 1..{MAX_BAUD} baud")
    if not 5 <= size <= 8:
        raise InvalidArgument(f"serial byte size {size} outside 5..8")
    if len(parity) != 1 or parity not in PARITIES:
        raise InvalidArgument(f"serial parity {parity!r}: one of {', '.join(PARITIES)}")
    if stop not in STOP_BITS:
        raise InvalidArgument(f"serial stop bits {stop / 10:g}: 1, 1.5 or 2")
    return {"baudrate": speed, "bytesize": size, "parity": parity, "stopbits": STOP_BITS[stop]}


class SerialStream:
    """The port ``name`` of ``ports`` streamed: opened with ``settings`` (pyserial's), read
    by a thread that calls ``push(bytes)`` (False: nobody takes them any more, the stream
    ends) and ``on_fail(reason)`` when the port fails. :class:`DeviceError` when the port
    is not allowed, busy or cannot be opened."""

    def __init__(
        self,
        ports: SerialPorts,
        name: str,
        settings: Mapping[str, Any],
        push: Callable[[bytes], bool],
        on_fail: Callable[[str], None],
    ) -> None:
        self.name = name
        self.settings = dict(settings)
        self._ports, self._push, self._on_fail = ports, push, on_fail
        self._port = ports.claim(name, settings)
        self._port.timeout = READ_POLL_S
        self._closed = threading.Event()
        self.bytes_in = 0  #: bytes read from the port and pushed
        self.bytes_out = 0  #: bytes written to the port
        self._reader = threading.Thread(target=self._read, name=f"hub-serial {name}",
                                        daemon=True)  # fmt: skip
        self._reader.start()
        log.info("serial %s: streamed at %s", name, settings)

    def apply(self, settings: Mapping[str, Any]) -> None:
        """New line settings (the client's program changed its own)."""
        try:
            self._port.apply_settings(dict(settings))
        except PORT_ERRORS as exc:
            raise DeviceError(f"serial port {self.name!r}: settings {dict(settings)} refused "
                              f"on the hub: {exc}") from None  # fmt: skip
        self.settings = dict(settings)

    def write(self, data: bytes) -> None:
        """Write ``data`` (at most :data:`MAX_STREAM_CHUNK` bytes) within its deadline;
        :class:`DeviceError` (the stream is then closed) when the port fails or the line does
        not take them in time."""
        if not 0 < len(data) <= MAX_STREAM_CHUNK:
            raise InvalidArgument(f"a serial write carries 1..{MAX_STREAM_CHUNK} bytes, "
                                  f"not {len(data)}")  # fmt: skip
        port = self._port
        port.write_timeout = write_deadline(self.settings, len(data))
        try:
            n = port.write(data)
        except PORT_ERRORS as exc:  # pyserial's SerialTimeoutException included
            self.close()
            raise DeviceError(f"serial port {self.name!r}: write failed: {exc}") from None
        self.bytes_out += n or 0

    def _read(self) -> None:
        port = self._port
        try:
            while not self._closed.is_set():
                data = port.read(max(1, min(port.in_waiting, MAX_STREAM_CHUNK)))
                if data and not self._closed.is_set():
                    self.bytes_in += len(data)
                    if not self._push(bytes(data)):
                        break
        except (*PORT_ERRORS, TypeError) as exc:  # pyserial's SerialException is an OSError
            if self._closed.is_set():
                return
            if isinstance(exc, TypeError) or not port.is_open:
                # closed under the read (the hub shutting down): pyserial sets its fd to None
                # before it says it is closed, and a read then fails on that None
                log.info("serial %s: the port was closed on the hub", self.name)
                self._on_fail(f"serial port {self.name!r} was closed on the hub")
            else:
                log.warning("serial %s: read failed: %s", self.name, exc)
                self._on_fail(f"serial port {self.name!r} failed on the hub: {exc}")

    def close(self) -> None:
        """Stop reading and give the port back (bounded, idempotent)."""
        if self._closed.is_set():
            return
        self._closed.set()
        cancel = getattr(self._port, "cancel_read", None)
        if cancel is not None:
            try:
                cancel()
            except (OSError, ValueError):
                pass
        if threading.current_thread() is not self._reader:
            self._reader.join(JOIN_S)
        self._ports.release(self.name)
        log.info("serial %s: stream ended (%d bytes in, %d out)", self.name, self.bytes_in,
                 self.bytes_out)  # fmt: skip
