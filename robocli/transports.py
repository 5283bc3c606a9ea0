"""Byte streams from a URL, like pyserial's ``serial_for_url``, knowing nothing of messages.

=================================  ============================================
``tcp://host:port`` / ``host:port``  TCP (``TCP_NODELAY``), e.g. MobileSim on 8101;
``[::1]:port``                      IPv6 literals in brackets
``/dev/ttyUSB0``, ``COM1``          a serial port at ``baudrate`` (8N1, raw)
``socket://``, ``rfc2217://``,      any pyserial URL handler
``loop://``, ``spy://``, ...
:func:`pair`                        two connected in-process ends, for tests
=================================  ============================================

Every transport has the same small interface: :meth:`Transport.read` returns what arrived
(``b""`` on timeout) and raises :class:`~robocli.errors.ConnectionLost` when the peer is gone;
:meth:`Transport.write` sends everything within its deadline or raises.
:class:`FaultyTransport` wraps any of them to split, drop, corrupt or delay incoming bytes
for robustness tests.

The base class and the write deadline live in :mod:`robocli.transport_base`; they are
importable from here. Addresses and URLs are read by one parser, :mod:`robocli.addresses`,
used by every command and client (:func:`parse_address`, :func:`parse_host`,
:func:`check_url`, :func:`is_tcp`, :func:`format_address`, :class:`InvalidURL`); its names
are re-exported here.
"""

from __future__ import annotations

import contextlib
import errno
import os
import random
import select
import socket
import time
from typing import Any

from robocli.addresses import (
    InvalidURL,
    check_url,
    format_address,
    is_tcp,
    parse_address,
    parse_host,
)
from robocli.errors import ConnectionLost, DeviceError, TransportError
from robocli.transport_base import (
    WRITE_TIMEOUT,
    Transport,
    _check_fresh,
    _poll,
    _write_timed_out,
)

__all__ = [
    "WRITE_TIMEOUT",
    "FaultyTransport",
    "InvalidURL",
    "SerialTransport",
    "SocketTransport",
    "Transport",
    "check_url",
    "format_address",
    "is_tcp",
    "list_serial_ports",
    "open_transport",
    "pair",
    "parse_address",
    "parse_host",
]


class SocketTransport(Transport):
    """A connected stream socket (TCP or a socketpair end), used non-blocking: reads wait with
    ``poll``, writes wait for room until their deadline."""

    def __init__(self, sock: socket.socket, url: str) -> None:
        super().__init__()
        self.sock = sock
        self.url = url
        self._fd = sock.fileno()
        if sock.family in (socket.AF_INET, socket.AF_INET6):
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.setblocking(False)

    @classmethod
    def connect(cls, host: str, port: int, timeout: float = 5.0) -> SocketTransport:
        url = f"tcp://{format_address(host.strip('[]'), port)}"
        try:
            sock = socket.create_connection((host.strip("[]"), port), timeout=timeout)
        except ConnectionRefusedError:
            raise TransportError(
                f"cannot connect to {url}: connection refused "
                "(is the robot, or its simulator `robocli sim ...`, listening there?)"
            ) from None
        except TimeoutError:
            raise TransportError(f"cannot connect to {url}: no answer in {timeout:g} s") from None
        except OSError as exc:
            raise TransportError(f"cannot connect to {url}: {exc.strerror or exc}") from None
        except UnicodeError as exc:  # the IDNA codec: an empty or over-long label, e.g. "a..b"
            why = str(exc.__cause__ or exc.__context__ or exc).removeprefix("UnicodeError: ")
            raise InvalidURL(f"bad host {host!r} in {url!r}: not a host name ({why})") from None
        return cls(sock, url)

    def read(self, size: int = 4096, timeout: float | None = None) -> bytes:
        """:meth:`Transport.read` (one call less on every read: it is the request path)."""
        if self._closed:
            raise ConnectionLost(f"{self.url}: transport is closed")
        # Try first, wait only when nothing is there: on loopback a reply is often in the
        # socket already by the time its request's send() returns.
        try:
            data = self.sock.recv(size)
        except BlockingIOError:
            if timeout == 0 or not _poll(self._fd, select.POLLIN, timeout):
                return b""
            try:
                data = self.sock.recv(size)
            except BlockingIOError:
                return b""
            except OSError as exc:
                raise ConnectionLost(f"{self.url}: {exc.strerror or exc}") from None
        except OSError as exc:
            raise ConnectionLost(f"{self.url}: {exc.strerror or exc}") from None
        if not data:
            raise ConnectionLost(f"{self.url}: connection closed by the peer")
        return data

    _read = read

    def _wait_readable(self, timeout: float) -> bool:
        return _poll(self._fd, select.POLLIN, timeout)

    def fileno(self) -> int | None:
        return self._fd

    def write(
        self, data: bytes, timeout: float | None = None, *, not_after: float | None = None
    ) -> None:
        """:meth:`Transport.write`, with a fast path: when no other write holds the socket
        and the kernel takes all of ``data`` at once (a request on an idle link), it goes in
        one non-blocking ``send`` that cannot miss any deadline; otherwise the general path."""
        lock = self._write_lock
        if self._closed or not lock.acquire(False):
            super().write(data, timeout, not_after=not_after)
            return
        try:
            _check_fresh(self.url, not_after)
            try:
                sent = self.sock.send(data)
            except BlockingIOError:
                sent = 0
            except OSError as exc:
                raise ConnectionLost(f"{self.url}: {exc.strerror or exc}") from None
            if sent < len(data):  # the rest waits for room (lock held), within the deadline
                limit = self.write_timeout if timeout is None else timeout
                self._write(bytes(data[sent:]), time.monotonic() + limit)
        finally:
            lock.release()

    def _write(self, data: bytes, deadline: float) -> None:
        view = memoryview(data)
        sent = 0
        while sent < len(data):
            try:
                sent += self.sock.send(view[sent:])
                continue
            except BlockingIOError:
                pass
            except OSError as exc:
                raise ConnectionLost(f"{self.url}: {exc.strerror or exc}") from None
            left = deadline - time.monotonic()
            if left <= 0 or not _poll(self._fd, select.POLLOUT, left):
                raise _write_timed_out(self.url, sent, len(data))

    def _close(self) -> None:
        try:
            self.sock.shutdown(socket.SHUT_RDWR)  # wakes a thread waiting in poll
        except OSError:
            pass
        self.sock.close()


class SerialTransport(Transport):
    """Any pyserial port: a device path, ``COM1``, or a pyserial URL."""

    def __init__(self, port: Any, url: str) -> None:
        super().__init__()
        self.port = port
        self.url = url
        try:
            self._fd: int | None = int(port.fileno())
        except (AttributeError, OSError, ValueError, TypeError):
            self._fd = None  # URL handlers (loop://, rfc2217://...) and Windows

    @classmethod
    def open(cls, url: str, baudrate: int = 9600) -> SerialTransport:
        import serial  # lazy: keeps `robocli --help` fast

        try:
            if "://" in url:
                port = serial.serial_for_url(url, baudrate=baudrate, timeout=0)
            elif os.name == "posix":  # flock: a second robocli on the port is refused
                port = serial.Serial(url, baudrate=baudrate, timeout=0, exclusive=True)
            else:  # Windows opens COM ports exclusively anyway
                port = serial.Serial(url, baudrate=baudrate, timeout=0)
        except (serial.SerialException, ValueError) as exc:
            if getattr(exc, "errno", None) in (errno.EAGAIN, errno.EWOULDBLOCK):
                raise DeviceError(
                    f"{url}: robot busy: another program holds this serial port "
                    f"(find it with `fuser {url}`)"
                ) from None
            why = _serial_error(exc) + _serial_hint(exc)
            raise TransportError(f"cannot open {url}: {why}") from None
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

    def _wait_readable(self, timeout: float) -> bool:
        if self._fd is None:
            return super()._wait_readable(timeout)
        return _poll(self._fd, select.POLLIN, timeout)

    def fileno(self) -> int | None:
        return self._fd

    def _pending_bytes(self) -> int:
        import serial

        try:
            return int(self.port.in_waiting)
        except (serial.SerialException, OSError) as exc:
            raise ConnectionLost(f"{self.url}: {exc}") from None

    def _write(self, data: bytes, deadline: float) -> None:
        import serial

        try:
            self.port.write_timeout = max(0.001, deadline - time.monotonic())
            self.port.write(data)
        except serial.SerialTimeoutException:
            raise _write_timed_out(self.url, 0, len(data)) from None
        except (serial.SerialException, OSError) as exc:
            raise ConnectionLost(f"{self.url}: {exc}") from None

    def _close(self) -> None:
        if self._fd is not None and os.name == "posix":
            import fcntl

            # unlock first: a reader thread still in poll() on the fd keeps the open file,
            # and with it the lock, alive after close() until its poll returns
            with contextlib.suppress(OSError):
                fcntl.flock(self._fd, fcntl.LOCK_UN)
        self.port.close()


def _serial_error(exc: BaseException) -> str:
    """pyserial's reason, once: its message nests the OS error in its own text, each with
    its errno ("[Errno 2] could not open port X: [Errno 2] No such file or directory: 'X'")."""
    code = getattr(exc, "errno", None)
    if code == errno.ENOENT:
        return f"{os.strerror(code)} (`robocli ports` lists the serial ports of this computer)"
    if isinstance(code, int) and code > 0:
        return os.strerror(code)
    args: tuple[Any, ...] = tuple(getattr(exc.__context__, "args", ()))
    if len(args) == 2 and args[0] == errno.ENOTTY:  # termios.error: a file, not a tty
        return f"not a serial port ({args[1]})"
    return str(exc)


def _serial_hint(exc: BaseException) -> str:
    """What a lab user should do about a serial port error they usually cannot read."""
    errno_ = getattr(exc, "errno", None)
    text = str(exc)
    if errno_ == 13 or "Permission denied" in text:
        return (
            " (on Linux, serial ports belong to the 'dialout' group: "
            "sudo usermod -aG dialout $USER, then log out and in again)"
        )
    if errno_ == 16 or "Device or resource busy" in text:
        return " (another program holds the port: close it, or find it with `fuser PORT`)"
    return ""


def open_transport(url: str, *, baudrate: int = 9600, timeout: float = 5.0) -> Transport:
    """Open a byte stream from ``url`` (see the module table). ``timeout`` bounds connecting.
    Raises :class:`InvalidURL` for a URL that names no stream (:func:`check_url`),
    :class:`TransportError` when the stream cannot be opened."""
    url = check_url(url)
    if is_tcp(url):
        host, port = parse_address(url)
        return SocketTransport.connect(host, port, timeout=timeout)
    return SerialTransport.open(url, baudrate=baudrate)


def list_serial_ports() -> list[dict[str, Any]]:
    """Serial ports as pyserial's ``list_ports`` sees them: device, description, hardware id
    (USB vendor:product and serial number), sorted by device name."""
    from serial.tools import list_ports

    return [{"device": p.device, "description": p.description, "hwid": p.hwid}
            for p in sorted(list_ports.comports(), key=lambda p: p.device)]  # fmt: skip


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

    def _write(self, data: bytes, deadline: float) -> None:
        self.inner.write(data, timeout=max(0.0, deadline - time.monotonic()))

    def _wait_readable(self, timeout: float) -> bool:
        return bool(self._pending) or self.inner.wait_readable(timeout)

    def _close(self) -> None:
        self.inner.close()
