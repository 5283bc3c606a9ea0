"""Byte streams from a URL, like pyserial's ``serial_for_url``, knowing nothing of messages.

=================================  ============================================
``tcp://host:port`` / ``host:port``  TCP (``TCP_NODELAY``), e.g. MobileSim on 8101
``/dev/ttyUSB0``, ``COM1``          a serial port at ``baudrate`` (8N1, raw)
``socket://``, ``rfc2217://``,      any pyserial URL handler
``loop://``, ``spy://``, ...
:func:`pair`                        two connected in-process ends, for tests
=================================  ============================================

Every transport has the same small interface: :meth:`Transport.read` returns what arrived
(``b""`` on timeout) and raises :class:`~robocli.errors.ConnectionLost` when the peer is gone;
:meth:`Transport.write` sends everything or raises. :class:`FaultyTransport` wraps any of them
to split, drop, corrupt or delay incoming bytes for robustness tests.
"""

from __future__ import annotations

import random
import re
import socket
import threading
import time
from typing import Any

from robocli.errors import ConnectionLost, TransportError

_TCP_URL = re.compile(r"^(?:tcp://)?(?P<host>\[[^\]]+\]|[A-Za-z0-9_.\-]+):(?P<port>\d{1,5})/?$")


class Transport:
    """A bidirectional byte stream. Subclasses implement ``_read``/``_write``/``_close``."""

    url: str = ""

    def __init__(self) -> None:
        self._closed = False
        self._write_lock = threading.Lock()

    def read(self, size: int = 4096, timeout: float | None = None) -> bytes:
        """Return up to ``size`` bytes, ``b""`` if none arrived within ``timeout`` seconds
        (``None`` blocks). Raises :class:`ConnectionLost` once the stream has ended."""
        if self._closed:
            raise ConnectionLost(f"{self.url}: transport is closed")
        return self._read(size, timeout)

    def write(self, data: bytes) -> None:
        """Send all of ``data`` (thread-safe: writes from several threads never interleave)."""
        if self._closed:
            raise ConnectionLost(f"{self.url}: transport is closed")
        with self._write_lock:
            self._write(bytes(data))

    def close(self) -> None:
        """Close the stream; idempotent."""
        if not self._closed:
            self._closed = True
            self._close()

    @property
    def closed(self) -> bool:
        return self._closed

    def __enter__(self) -> Transport:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.url}{' closed' if self._closed else ''}>"

    # -- to implement
    def _read(self, size: int, timeout: float | None) -> bytes:
        raise NotImplementedError

    def _write(self, data: bytes) -> None:
        raise NotImplementedError

    def _close(self) -> None:
        raise NotImplementedError


class SocketTransport(Transport):
    """A connected stream socket (TCP or a socketpair end)."""

    def __init__(self, sock: socket.socket, url: str) -> None:
        super().__init__()
        self.sock = sock
        self.url = url
        self._timeout: float | None | str = "unset"
        if sock.family in (socket.AF_INET, socket.AF_INET6):
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    @classmethod
    def connect(cls, host: str, port: int, timeout: float = 5.0) -> SocketTransport:
        url = f"tcp://{host}:{port}"
        try:
            sock = socket.create_connection((host.strip("[]"), port), timeout=timeout)
        except ConnectionRefusedError:
            raise TransportError(
                f"cannot connect to {url}: connection refused "
                "(is the robot, or `robocli sim pioneer`, listening there?)"
            ) from None
        except TimeoutError:
            raise TransportError(f"cannot connect to {url}: no answer in {timeout:g} s") from None
        except OSError as exc:
            raise TransportError(f"cannot connect to {url}: {exc.strerror or exc}") from None
        return cls(sock, url)

    def _read(self, size: int, timeout: float | None) -> bytes:
        if timeout != self._timeout:
            self.sock.settimeout(timeout)
            self._timeout = timeout
        try:
            data = self.sock.recv(size)
        except (TimeoutError, BlockingIOError):
            return b""
        except OSError as exc:
            raise ConnectionLost(f"{self.url}: {exc.strerror or exc}") from None
        if not data:
            raise ConnectionLost(f"{self.url}: connection closed by the peer")
        return data

    def _write(self, data: bytes) -> None:
        try:
            self.sock.sendall(data)
        except OSError as exc:
            raise ConnectionLost(f"{self.url}: {exc.strerror or exc}") from None

    def _close(self) -> None:
        try:
            self.sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self.sock.close()


class SerialTransport(Transport):
    """Any pyserial port: a device path, ``COM1``, or a pyserial URL."""

    def __init__(self, port: Any, url: str) -> None:
        super().__init__()
        self.port = port
        self.url = url

    @classmethod
    def open(cls, url: str, baudrate: int = 9600) -> SerialTransport:
        import serial  # lazy: keeps `robocli --help` fast

        try:
            if "://" in url:
                port = serial.serial_for_url(url, baudrate=baudrate, timeout=0)
            else:
                port = serial.Serial(url, baudrate=baudrate, timeout=0)
        except (serial.SerialException, ValueError) as exc:
            raise TransportError(f"cannot open {url}: {exc}") from None
        return cls(port, url)

    def _read(self, size: int, timeout: float | None) -> bytes:
        import serial

        try:
            if self.port.timeout != timeout:
                self.port.timeout = timeout
            waiting = self.port.in_waiting
            data = bytes(self.port.read(min(size, waiting) if waiting else 1))
            if data and self.port.in_waiting:
                data += bytes(self.port.read(min(size - len(data), self.port.in_waiting)))
        except (serial.SerialException, OSError) as exc:
            raise ConnectionLost(f"{self.url}: {exc}") from None
        except (TypeError, AttributeError):  # pyserial, when closed by another thread
            if self._closed:
                raise ConnectionLost(f"{self.url}: transport is closed") from None
            raise
        return data

    def _write(self, data: bytes) -> None:
        import serial

        try:
            self.port.write(data)
        except (serial.SerialException, OSError) as exc:
            raise ConnectionLost(f"{self.url}: {exc}") from None

    def _close(self) -> None:
        self.port.close()


def open_transport(url: str, *, baudrate: int = 9600, timeout: float = 5.0) -> Transport:
    """Open a byte stream from ``url`` (see the module table). ``timeout`` bounds connecting."""
    url = url.strip()
    if not url:
        raise TransportError("empty port or URL")
    match = _TCP_URL.match(url)
    if match and (url.startswith("tcp://") or not url.startswith("/")):
        port = int(match["port"])
        if not 0 < port < 65536:
            raise TransportError(f"bad TCP port in {url!r}")
        return SocketTransport.connect(match["host"], port, timeout=timeout)
    if url.startswith("tcp://"):
        raise TransportError(f"bad TCP URL {url!r}: expected tcp://host:port")
    return SerialTransport.open(url, baudrate=baudrate)


def pair() -> tuple[SocketTransport, SocketTransport]:
    """Two connected in-process transports (a socketpair), for tests and embedding."""
    a, b = socket.socketpair()
    return SocketTransport(a, "pair://a"), SocketTransport(b, "pair://b")


class FaultyTransport(Transport):
    """Wraps a transport and injects faults into what it reads (seeded, reproducible).

    ``split``: deliver reads in random chunks of 1..split bytes; ``drop``: probability that a
    byte is lost; ``corrupt``: probability that a byte has one bit flipped; ``delay``: seconds
    to wait before each read returns data. Counters say what was injected.
    """

    def __init__(
        self,
        inner: Transport,
        *,
        split: int = 0,
        drop: float = 0.0,
        corrupt: float = 0.0,
        delay: float = 0.0,
        seed: int = 0,
    ) -> None:
        super().__init__()
        self.inner = inner
        self.url = f"faulty+{inner.url}"
        self.split, self.drop, self.corrupt, self.delay = split, drop, corrupt, delay
        self._rng = random.Random(seed)
        self._pending = b""
        self.dropped = 0
        self.corrupted = 0

    def _read(self, size: int, timeout: float | None) -> bytes:
        if not self._pending:
            self._pending = self._mangle(self.inner.read(size, timeout))
            if not self._pending:
                return b""
        n = len(self._pending)
        if self.split:
            n = min(n, self._rng.randint(1, self.split))
        n = min(n, size)
        out, self._pending = self._pending[:n], self._pending[n:]
        if self.delay:
            time.sleep(self.delay)
        return out

    def _mangle(self, data: bytes) -> bytes:
        if not (self.drop or self.corrupt) or not data:
            return data
        out = bytearray()
        for byte in data:
            if self.drop and self._rng.random() < self.drop:
                self.dropped += 1
                continue
            if self.corrupt and self._rng.random() < self.corrupt:
                byte ^= 1 << self._rng.randrange(8)
                self.corrupted += 1
            out.append(byte)
        return bytes(out)

    def _write(self, data: bytes) -> None:
        self.inner.write(data)

    def _close(self) -> None:
        self.inner.close()
