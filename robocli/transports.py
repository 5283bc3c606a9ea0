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

Addresses and URLs are read by one parser, used by every command and client:
:func:`parse_address` (``HOST[:PORT]``, ``[IPv6]:PORT``), :func:`parse_host` (an address
without a port, e.g. where to listen), :func:`check_url` (what :func:`open_transport`
accepts, checked without opening anything) and :func:`format_address` (back to text).
Each refuses a malformed value with :class:`InvalidURL`, a usage error.
"""

from __future__ import annotations

import contextlib
import errno
import ipaddress
import math
import os
import random
import re
import select
import socket
import threading
import time
from typing import Any

from robocli.errors import ConnectionLost, DeviceError, InvalidArgument, TransportError

#: A host name (or an IPv4 address): letters, digits, ``_``, ``.``, ``-``.
_HOSTNAME = re.compile(r"^[A-Za-z0-9_.\-]+$")
#: A Windows serial port name (``COM1``), which has no slash.
_COM_PORT = re.compile(r"^COM\d+$", re.IGNORECASE)
#: pyserial URL schemes whose part after ``://`` is ``HOST:PORT``.
_NETWORK_SCHEMES = ("socket", "rfc2217")


class InvalidURL(InvalidArgument, TransportError):
    """An address, port or URL that cannot name a stream (bad port number, two ports,
    unknown scheme): the caller's mistake, so a usage error (exit code 2); also a
    :class:`TransportError` for code that catches those around :func:`open_transport`.
    :attr:`reason` is what is wrong, without the value (for callers that rephrase)."""

    def __init__(self, message: str, reason: str = "") -> None:
        super().__init__(message)
        self.reason = reason or message


def _bad(what: str, text: str, reason: str, form: str = "") -> InvalidURL:
    expected = f"; expected {form}" if form else ""
    return InvalidURL(f"{what} {text!r}: {reason}{expected}", reason)


def _is_ipv6(text: str) -> bool:
    try:
        ipaddress.IPv6Address(text)  # a zone (fe80::1%eth0) included
    except ValueError:
        return False
    return True


def _check_host(host: str, text: str, what: str, form: str) -> str:
    if _is_ipv6(host) or _HOSTNAME.match(host):
        return host
    which = "" if host == text.strip() else f"{host!r} "
    raise _bad(what, text, f"{which}is not a host name or address", form)


def parse_address(
    text: str,
    default_port: int | None = None,
    *,
    default_host: str | None = None,
    what: str = "address",
    form: str | None = None,
    port_range: tuple[int, int] = (1, 65535),
) -> tuple[str, int]:
    """``HOST``, ``HOST:PORT``, ``[IPv6]:PORT``, a bare IPv6 literal, each optionally after
    ``tcp://`` -> ``(host, port)``, the host without brackets.

    ``default_port``: the port when none is given (None: a port is required).
    ``default_host``: the host when none is given (``:PORT``, or ``PORT`` alone; None: a
    host is required). ``what`` names the value in messages (``--hub``), ``form`` says what
    is expected there (default ``HOST:PORT`` or ``HOST[:PORT]``). Raises :class:`InvalidURL`
    (a usage error) for anything else: two ports (``h:1:2``), a port out of ``port_range``,
    a host that is no name or address; nothing is resolved or connected."""
    if form is None:
        form = ("HOST:PORT" if default_port is None else "HOST[:PORT]") + " ([ADDR]:PORT for IPv6)"
    t = text.strip()
    if t.startswith("tcp://"):
        t = t[len("tcp://") :].removesuffix("/")
    port_text: str | None = None
    if t.startswith("["):
        host, bracket, rest = t[1:].partition("]")
        if not bracket or not _is_ipv6(host):
            raise _bad(what, text, "brackets hold an IPv6 address", form)
        if rest:
            if not rest.startswith(":"):
                raise _bad(what, text, f"{rest!r} after the address", form)
            port_text = rest[1:]
    elif t.count(":") > 1:
        if not _is_ipv6(t):
            raise _bad(what, text, "more than one ':'", form)
        host = t  # a bare IPv6 literal: no port can follow it
    elif ":" in t:
        host, _, port_text = t.partition(":")
    elif t.isdigit() and default_host is not None:
        host, port_text = "", t  # a port alone
    else:
        host = t
    if not host:
        if default_host is None:
            raise _bad(what, text, "no host", form)
        host = default_host
    else:
        host = _check_host(host, text, what, form)
    low, high = port_range
    if port_text is None:
        if default_port is None:
            raise _bad(what, text, "no port", form)
        return host, default_port
    if not port_text.isdigit() or not port_text.isascii():
        shown = repr(port_text) if port_text else "nothing"
        raise _bad(what, text, f"bad port ({shown} after ':')", form)
    port = int(port_text)
    if not low <= port <= high:
        raise _bad(what, text, f"port {port} out of range {low}..{high}", form)
    return host, port


def parse_host(text: str, *, what: str = "address") -> str:
    """A host name, IPv4 address or IPv6 literal (with or without brackets), without a
    port -> the host (IPv6 without brackets), e.g. where a server listens. Raises
    :class:`InvalidURL` for anything else (an empty value, a port, spaces)."""
    t = text.strip()
    if t.startswith("[") and t.endswith("]") and _is_ipv6(t[1:-1]):
        return t[1:-1]
    if _is_ipv6(t) or (t and _HOSTNAME.match(t)):
        return t
    if t and (t.count(":") == 1 or t.startswith("[")):
        raise _bad(what, text, "give the address without a port")
    raise _bad(what, text, "not a host name or address (e.g. 127.0.0.1, ::1)")


def format_address(host: str, port: int) -> str:
    """``host:port`` as :func:`parse_address` reads it back: IPv6 literals in brackets."""
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def check_url(url: str, *, what: str = "PORT") -> str:
    """``url`` stripped, when :func:`open_transport` can open it as something: ``tcp://``
    or ``HOST:PORT`` (:func:`parse_address`), a serial port (a path, ``COMn``), a pyserial
    URL whose scheme has a handler (``socket://HOST:PORT`` checked too). Else
    :class:`InvalidURL`, a usage error naming ``what``. Nothing is opened: a robot that is
    away is not a malformed URL."""
    text = url.strip()
    hint = "give a serial port (/dev/ttyUSB0, COM1), tcp://HOST:PORT or a pyserial URL"
    if not text:
        raise InvalidURL(f"{what}: empty; {hint}", "empty")
    if is_tcp(text):
        parse_address(text, what=what, form="tcp://HOST:PORT or HOST:PORT")
        return text
    if "://" in text:
        scheme, _, rest = text.partition("://")
        if not _pyserial_scheme(scheme):
            reason = f"unknown URL scheme {scheme!r}"
            raise InvalidURL(f"{what}: {reason} in {text!r}; {hint}", reason)
        if scheme in _NETWORK_SCHEMES:
            try:
                parse_address(rest.split("?", 1)[0].removesuffix("/"))
            except InvalidURL as exc:
                raise _bad(what, text, exc.reason, f"{scheme}://HOST:PORT") from None
        return text
    if _is_path(text) or os.path.exists(text):
        return text
    guess = f"/dev/{text}"
    also = f" (did you mean {guess}?)" if os.path.exists(guess) else ""
    reason = f"neither a serial port nor a TCP address{also}"
    raise InvalidURL(f"{what} {text!r} is {reason}; {hint}", reason)


def _is_path(text: str) -> bool:
    """A serial port's name: a path (``/dev/ttyUSB0``, ``./pty``, ``\\\\.\\COM10``) or ``COMn``."""
    return text.startswith(("/", ".", "\\")) or bool(_COM_PORT.match(text))


def is_tcp(text: str) -> bool:
    """Whether :func:`open_transport` takes ``text`` (stripped) as TCP: ``tcp://...``, or
    ``HOST:PORT``, a colon in what is neither a path nor another URL."""
    return text.startswith("tcp://") or (":" in text and "://" not in text and not _is_path(text))


#: Default deadline of one write, in seconds: past it the peer is taken as not reading.
WRITE_TIMEOUT = 1.0


class Transport:
    """A bidirectional byte stream. Subclasses implement ``_read``/``_write``/``_close`` and,
    where they can, ``_wait_readable``.

    Every write has a deadline (:attr:`write_timeout`, about 1 s by default): a peer that stops
    reading makes :meth:`write` raise :class:`~robocli.errors.TransportError`, never hang.
    """

    url: str = ""

    def __init__(self) -> None:
        self._closed = False
        self._write_lock = threading.Lock()
        self.write_timeout = WRITE_TIMEOUT

    def read(self, size: int = 4096, timeout: float | None = None) -> bytes:
        """Return up to ``size`` bytes, ``b""`` if none arrived within ``timeout`` seconds
        (``None`` blocks, ``0`` only takes what is there). Raises :class:`ConnectionLost` once
        the stream has ended."""
        if self._closed:
            raise ConnectionLost(f"{self.url}: transport is closed")
        return self._read(size, timeout)

    def wait_readable(self, timeout: float) -> bool:
        """True when a :meth:`read` would return data (or report the end of the stream)
        without waiting; False after ``timeout`` seconds. Consumes nothing."""
        if self._closed:
            raise ConnectionLost(f"{self.url}: transport is closed")
        return self._wait_readable(timeout)

    def fileno(self) -> int | None:
        """The file descriptor to wait on with ``poll``/``select``, or None when the stream
        has none (pyserial URL handlers, wrapped transports): use :meth:`wait_readable`."""
        return None

    def write(self, data: bytes, timeout: float | None = None) -> None:
        """Send all of ``data`` within ``timeout`` seconds (default :attr:`write_timeout`),
        else raise :class:`TransportError`. Thread-safe: writes from several threads never
        interleave; waiting for another thread's write counts against the deadline."""
        if self._closed:
            raise ConnectionLost(f"{self.url}: transport is closed")
        limit = self.write_timeout if timeout is None else timeout
        deadline = time.monotonic() + limit
        if not self._write_lock.acquire(timeout=max(limit, 0.0)):
            raise TransportError(
                f"{self.url}: write blocked for {limit:g} s by another write "
                "(the peer is not reading)"
            )
        try:
            if self._closed:
                raise ConnectionLost(f"{self.url}: transport is closed")
            self._write(bytes(data), deadline)
        finally:
            self._write_lock.release()

    def close(self) -> None:
        """Close the stream; idempotent, never waits for a blocked write."""
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

    def _write(self, data: bytes, deadline: float) -> None:
        raise NotImplementedError

    def _close(self) -> None:
        raise NotImplementedError

    def _wait_readable(self, timeout: float) -> bool:
        """Fallback for streams without a file descriptor: look every 2 ms."""
        deadline = time.monotonic() + timeout
        while True:
            if self._pending_bytes():
                return True
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            time.sleep(min(0.002, left))

    def _pending_bytes(self) -> int:
        raise NotImplementedError


def _write_timed_out(url: str, sent: int, total: int) -> TransportError:
    return TransportError(
        f"{url}: write timed out ({sent} of {total} bytes sent; the peer is not reading)"
    )


def _poll(fd: int, events: int, timeout: float | None) -> bool:
    """Wait until ``fd`` has one of ``events`` (or an error/hang-up); ``None`` waits forever."""
    poller = select.poll()
    poller.register(fd, events)
    ms = None if timeout is None else max(0, math.ceil(timeout * 1000))
    while True:
        try:
            return bool(poller.poll(ms))
        except InterruptedError:  # pragma: no cover - PEP 475 retries already
            continue


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

    def write(self, data: bytes, timeout: float | None = None) -> None:
        """:meth:`Transport.write`, with a fast path: when no other write holds the socket
        and the kernel takes all of ``data`` at once (a request on an idle link), it goes in
        one non-blocking ``send`` that cannot miss any deadline; otherwise the general path."""
        lock = self._write_lock
        if self._closed or not lock.acquire(False):
            super().write(data, timeout)
            return
        try:
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


def _pyserial_scheme(scheme: str) -> bool:
    """Whether pyserial has a URL handler for ``scheme`` (``socket``, ``rfc2217``...)."""
    import importlib.util

    if not scheme.isidentifier():
        return False
    try:
        return importlib.util.find_spec(f"serial.urlhandler.protocol_{scheme}") is not None
    except (ImportError, ValueError):
        return False


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
