"""Transports over real sockets, pyserial URLs and a pseudo-terminal."""

from __future__ import annotations

import os
import socket
import threading
import tty

import pytest

from robocli.errors import ConnectionLost, TransportError
from robocli.transports import FaultyTransport, SerialTransport, open_transport, pair


@pytest.fixture
def echo_server():
    srv = socket.create_server(("127.0.0.1", 0))
    port = srv.getsockname()[1]

    def serve() -> None:
        conn, _ = srv.accept()
        with conn:
            while data := conn.recv(4096):
                conn.sendall(data)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    yield port
    srv.close()


def _read_exactly(t, n: int) -> bytes:
    out = b""
    while len(out) < n:
        out += t.read(n - len(out), timeout=2.0)
    return out


@pytest.mark.parametrize("form", ["tcp://127.0.0.1:{}", "127.0.0.1:{}", "localhost:{}"])
def test_tcp_urls_round_trip(echo_server: int, form: str) -> None:
    with open_transport(form.format(echo_server)) as t:
        t.write(b"\xfa\xfb\x03\x00\x00\x00")
        assert _read_exactly(t, 6) == b"\xfa\xfb\x03\x00\x00\x00"
        assert t.read(10, timeout=0.01) == b""  # timeout gives empty bytes


def test_refused_port_is_a_clear_transport_error() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # bound, not listening: refused
        with pytest.raises(TransportError, match="connection refused"):
            open_transport(f"tcp://127.0.0.1:{port}")


@pytest.mark.parametrize("url", ["tcp://nohost", "", "/dev/robocli-does-not-exist"])
def test_bad_urls_raise_transport_error(url: str) -> None:
    with pytest.raises(TransportError):
        open_transport(url)


def test_peer_close_is_connection_lost() -> None:
    a, b = pair()
    b.close()
    with pytest.raises(ConnectionLost):
        a.read(10, timeout=1.0)
    with pytest.raises(ConnectionLost):
        b.write(b"x")


def test_pyserial_loop_url() -> None:
    with open_transport("loop://", baudrate=115200) as t:
        assert isinstance(t, SerialTransport)
        t.write(b"hello")
        assert _read_exactly(t, 5) == b"hello"


def test_serial_path_over_a_pty() -> None:
    master, slave = os.openpty()
    tty.setraw(slave)
    try:
        with open_transport(os.ttyname(slave), baudrate=9600) as t:
            os.write(master, b"\xfa\xfb\x03\x01\x00\x01")
            assert _read_exactly(t, 6) == b"\xfa\xfb\x03\x01\x00\x01"
            t.write(b"ping")
            assert os.read(master, 4) == b"ping"
    finally:
        os.close(master)
        os.close(slave)


def test_faulty_transport_splits_drops_and_corrupts_reproducibly() -> None:
    data = bytes(range(256)) * 8
    results = []
    for _ in range(2):
        a, b = pair()
        faulty = FaultyTransport(b, split=7, drop=0.05, corrupt=0.05, seed=42)
        a.write(data)
        got = b""
        chunks = 0
        while len(got) < len(data) - faulty.dropped:
            chunk = faulty.read(4096, timeout=1.0)
            assert 0 < len(chunk) <= 7
            got += chunk
            chunks += 1
        assert faulty.dropped > 0 and faulty.corrupted > 0
        assert len(got) == len(data) - faulty.dropped
        results.append((got, faulty.dropped, faulty.corrupted))
        a.close()
        faulty.close()
    assert results[0] == results[1]
