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


def test_a_write_the_peer_takes_only_in_part_keeps_its_deadline_and_its_bytes() -> None:
    a, b = pair()
    with a, b:
        big = bytes(range(256)) * 40_000  # 10 MB: far more than the socket buffers hold
        with pytest.raises(TransportError, match="write timed out"):
            a.write(big, timeout=0.2)  # nobody reads: the deadline, not a hang
    a, b = pair()
    with a, b:
        data = bytes(range(256)) * 4_000  # 1 MB, read as it comes by another thread
        got = bytearray()

        def reader() -> None:
            while len(got) < len(data):
                got.extend(b.read(65536, timeout=2.0))

        thread = threading.Thread(target=reader)
        thread.start()
        a.write(data, timeout=5.0)
        a.write(b"end", timeout=5.0)
        thread.join(5.0)
        assert bytes(got[: len(data)]) == data  # nothing lost or reordered past a short send


def test_writes_from_two_threads_never_interleave() -> None:
    a, b = pair()
    with a, b:
        n = 600_000  # each write needs several sends: the socket buffer is smaller
        got = bytearray()

        def reader() -> None:
            while len(got) < 2 * n:
                got.extend(b.read(65536, timeout=2.0))

        threads = [threading.Thread(target=reader)]
        threads += [threading.Thread(target=a.write, args=(c * n, 5.0)) for c in (b"A", b"B")]
        for t in threads:
            t.start()
        for t in threads:
            t.join(5.0)
        assert bytes(got) in (b"A" * n + b"B" * n, b"B" * n + b"A" * n)
