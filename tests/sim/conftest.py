"""Fixtures of the simulator tests: simulators on ephemeral ports and a raw ARCOS client.

The client is deliberately independent of the code under test: it builds packets with
``robocli.protocols.arcos`` and splits the server's stream with a strict pure-Python parser
(any byte that is not part of a well-formed frame fails the test).
"""

from __future__ import annotations

import collections
import socket
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from robocli.protocols import arcos
from robocli.sim.pioneer.server import PioneerSim


class RawClient:
    """A bare ARCOS client over a socket (or any object with send/recv callables)."""

    def __init__(self, send: Callable[[bytes], None], recv: Callable[[float], bytes]) -> None:
        self._send, self._recv = send, recv
        self._buf = bytearray()
        self._queue: collections.deque[bytes] = collections.deque()
        self.log: list[tuple[float, bytes]] = []  #: (arrival monotonic time, payload)

    @classmethod
    def tcp(cls, url: str) -> RawClient:
        host, port = url.removeprefix("tcp://").rsplit(":", 1)
        sock = socket.create_connection((host, int(port)), timeout=2.0)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

        def recv(timeout: float) -> bytes:
            sock.settimeout(max(timeout, 1e-4))
            try:
                data = sock.recv(65536)
            except TimeoutError:
                return b""
            if not data:
                raise ConnectionError("server closed the connection")
            return data

        client = cls(sock.sendall, recv)
        client.sock = sock  # type: ignore[attr-defined]
        return client

    def close(self) -> None:
        sock = getattr(self, "sock", None)
        if sock is not None:
            sock.close()

    # ------------------------------------------------------------ sending

    def send(self, command: int, arg: int | str | bytes | None = None) -> None:
        self._send(arcos.encode_command(command, arg))

    def send_raw(self, data: bytes) -> None:
        self._send(data)

    # ------------------------------------------------------------ receiving

    def _split(self) -> list[bytes]:
        out = []
        buf = self._buf
        while len(buf) >= 3:
            assert buf[:2] == arcos.SYNC, f"server sent garbage: {bytes(buf[:16]).hex(' ')}"
            total = buf[2] + 3
            if len(buf) < total:
                break
            out.append(arcos.unframe(bytes(buf[:total])))
            del buf[:total]
        return out

    def pump(self, timeout: float) -> None:
        """One read of at most ``timeout`` seconds; frames go to the queue and the log."""
        self._buf += self._recv(timeout)
        now = time.monotonic()
        for f in self._split():
            self.log.append((now, f))
            self._queue.append(f)

    def next(self, timeout: float = 2.0) -> bytes | None:
        """The next payload (type + data), or None if nothing arrives within ``timeout``."""
        deadline = time.monotonic() + timeout
        while not self._queue:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            self.pump(left)
        return self._queue.popleft()

    def expect(self, ptype: int, timeout: float = 2.0) -> bytes:
        """The next payload of type ``ptype``; payloads of other types are discarded."""
        deadline = time.monotonic() + timeout
        while True:
            p = self.next(max(0.0, deadline - time.monotonic()))
            if p is None:
                raise AssertionError(f"no packet of type {ptype:#04x} within {timeout} s")
            if p[0] == ptype:
                return p

    def sip(self, timeout: float = 2.0) -> dict[str, Any]:
        return arcos.decode_sip(self.expect(arcos.PacketType.SIP, timeout)[1:])

    def sips(self, n: int, timeout: float = 5.0) -> list[dict[str, Any]]:
        deadline = time.monotonic() + timeout
        return [self.sip(max(0.01, deadline - time.monotonic())) for _ in range(n)]

    def collect(self, duration: float) -> list[bytes]:
        """Everything that arrives within ``duration`` seconds (plus what was queued)."""
        deadline = time.monotonic() + duration
        while (left := deadline - time.monotonic()) > 0:
            self.pump(left)
        got = list(self._queue)
        self._queue.clear()
        return got

    def drain(self, quiet: float = 0.05, limit: float = 3.0) -> list[bytes]:
        """Everything until the line is quiet for ``quiet`` s (at most ``limit`` s)."""
        got = []
        deadline = time.monotonic() + limit
        while time.monotonic() < deadline and (p := self.next(quiet)) is not None:
            got.append(p)
        return got

    def flush(self) -> list[bytes]:
        """Everything already received (nothing is waited for)."""
        while True:
            n = len(self._buf) + len(self._queue)
            self.pump(0.0)
            if len(self._buf) + len(self._queue) == n:
                break
        got = list(self._queue)
        self._queue.clear()
        return got

    def latest_sip(self, timeout: float = 2.0) -> dict[str, Any]:
        """The first SIP sent after now (the backlog is discarded)."""
        self.flush()
        return self.sip(timeout)

    # ------------------------------------------------------------ the protocol

    def handshake(self) -> list[bytes]:
        replies = []
        for n in (0, 1, 2):
            self.send_raw(arcos.frame(bytes((n,))))
            replies.append(self.expect(n))
        return replies

    def open_session(self, *, enable: bool = False) -> None:
        self.handshake()
        self.send(arcos.Command.OPEN, 1)
        if enable:
            self.send(arcos.Command.ENABLE, 1)
        self.sip()


@pytest.fixture
def make_sim() -> Iterator[Callable[..., PioneerSim]]:
    """Factory: ``make_sim(**kw)`` -> a simulator serving TCP on an ephemeral port."""
    sims: list[PioneerSim] = []

    def make(**kw: Any) -> PioneerSim:
        sim = PioneerSim(**kw)
        sims.append(sim)
        sim.serve_tcp(port=0)
        return sim

    yield make
    for sim in sims:
        sim.close()


@pytest.fixture
def open_pty() -> Iterator[Callable[[str], RawClient]]:
    """Factory: ``open_pty(path)`` -> a RawClient on a serial device, via pyserial."""
    serial = pytest.importorskip("serial")
    ports: list[Any] = []

    def make(path: str) -> RawClient:
        port = serial.Serial(path, baudrate=9600, timeout=0.05)
        ports.append(port)
        port.reset_input_buffer()
        return RawClient(port.write, lambda timeout: port.read(max(1, port.in_waiting)))

    yield make
    for port in ports:
        port.close()


@pytest.fixture
def connect() -> Iterator[Callable[[PioneerSim], RawClient]]:
    """Factory: ``connect(sim)`` -> a RawClient on the simulator's TCP port."""
    clients: list[RawClient] = []

    def make(sim: PioneerSim) -> RawClient:
        assert sim.url is not None
        c = RawClient.tcp(sim.url)
        clients.append(c)
        return c

    yield make
    for c in clients:
        c.close()
