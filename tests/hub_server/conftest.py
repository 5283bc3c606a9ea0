"""Hub server tests: a hub on an ephemeral loopback port, and a raw ros4mat client that
speaks only bytes built with :mod:`robocli.protocols.ros4mat`."""

from __future__ import annotations

import socket
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from robocli.hub_server import HubServer
from robocli.protocols import ros4mat as r4m
from tests.waiting import wait_for

TIMEOUT = 10.0


class RawClient:
    """A ros4mat client made of sockets and the protocol module only."""

    def __init__(self, port: int, timeout: float = TIMEOUT) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=timeout)
        self.client_id = 0

    def send(self, data: bytes) -> None:
        self.sock.sendall(data)

    def _exact(self, n: int) -> bytes:
        buf = bytearray()
        while len(buf) < n:
            chunk = self.sock.recv(n - len(buf))
            if not chunk:
                raise ConnectionError(f"closed after {len(buf)} of {n} bytes")
            buf += chunk
        return bytes(buf)

    def recv_raw(self) -> bytes:
        """One whole reply packet, as bytes."""
        head = self._exact(r4m.HEADER_SIZE)
        return head + self._exact(r4m.body_length(r4m.Header.parse(head)))

    def recv(self) -> r4m.DecodedPacket:
        return r4m.decode(self.recv_raw())

    def request(self, kind: Any, body: Any = None) -> r4m.DecodedPacket:
        self.send(r4m.encode_request(kind, body, client_id=self.client_id))
        return self.recv()

    def connect(self, compress: bool = False, client_id: int = 0, token: bytes = b"") -> int:
        self.client_id = client_id
        body = bytes([r4m.PROTOCOL_VERSION, 1 if compress else 0]) + token
        ack = self.request(r4m.MsgType.CONNECT, body)
        assert ack.msg_type == r4m.MsgType.CONNECT_ACK and ack.error == 0, ack
        self.client_id = ack.client_id
        return ack.client_id

    def subscribe(
        self, sensor: str, params: Any = None, buffer: int = 0, silent: bool = False
    ) -> r4m.DecodedPacket:
        body = {"sensor": sensor, "silent": int(silent), "buffer_size": buffer, "params": params}
        return self.request(r4m.MsgType.SUBSCRIBE, body)

    def pull(self, sensor: str) -> r4m.DecodedPacket:
        reply = self.request(sensor)
        assert reply.msg_type == r4m.sensor_type(sensor), reply
        return reply

    def close(self) -> None:
        self.sock.close()


@pytest.fixture
def client_factory(hub: HubServer) -> Iterator[Callable[..., RawClient]]:
    """``client_factory()``: a new raw client of ``hub`` (closed after the test);
    ``client_factory(connected=True)``: one that has sent CONNECT already."""
    made: list[RawClient] = []

    def make(connected: bool = False) -> RawClient:
        c = RawClient(hub.port)
        made.append(c)
        if connected:
            c.connect()
        return c

    yield make
    for c in made:
        c.close()


@pytest.fixture
def raw() -> type[RawClient]:
    """The raw client class (tests build their own hubs)."""
    return RawClient


@pytest.fixture
def wait() -> Callable[..., Any]:
    return wait_for
