"""Transports over real sockets, pyserial URLs and a pseudo-terminal."""

from __future__ import annotations

import os
import socket
import threading
import tty

import pytest

from robocli.errors import ConnectionLost, InvalidArgument, TransportError
from robocli.transports import (
    FaultyTransport,
    InvalidURL,
    SerialTransport,
    check_url,
    format_address,
    open_transport,
    pair,
    parse_address,
    parse_host,
)
from tests.peers import needs_ipv6


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


@pytest.mark.parametrize(
    ("text", "kwargs", "expected"),
    [
        ("10.0.0.2", {"default_port": 1500}, ("10.0.0.2", 1500)),
        ("robot.local:8101", {}, ("robot.local", 8101)),
        ("tcp://h:1600/", {}, ("h", 1600)),
        ("[::1]:11500", {}, ("::1", 11500)),
        ("tcp://[fe80::1%eth0]:80", {}, ("fe80::1%eth0", 80)),
        ("::1", {"default_port": 1500}, ("::1", 1500)),  # a bare IPv6 literal has no port
        ("[::1]", {"default_port": 1500}, ("::1", 1500)),
        (":7", {"default_port": 1500, "default_host": "127.0.0.1"}, ("127.0.0.1", 7)),
        ("1501", {"default_port": 1, "default_host": "127.0.0.1"}, ("127.0.0.1", 1501)),
        ("0", {"default_host": "h", "port_range": (0, 65533)}, ("h", 0)),
    ],
)
def test_parse_address_reads_every_form(text: str, kwargs: dict, expected: tuple) -> None:
    assert parse_address(text, **kwargs) == expected


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("127.0.0.1:11500:99", "more than one ':'"),  # was read as port 99
        ("h:x", "bad port ('x'"),
        ("robot:", "bad port (nothing"),
        ("h:99999", "port 99999 out of range"),
        ("h:0", "port 0 out of range"),
        ("h:+80", "bad port"),
        ("[::1", "brackets hold an IPv6 address"),
        ("[10.0.0.1]:80", "brackets hold an IPv6 address"),
        ("[::1]x", "'x' after the address"),
        ("bad host:80", "not a host name"),
        (":80", "no host"),
        ("h", "no port"),
    ],
)
def test_parse_address_refuses_with_a_usage_error(text: str, reason: str) -> None:
    with pytest.raises(InvalidURL) as info:
        parse_address(text, what="--hub")
    assert isinstance(info.value, InvalidArgument) and info.value.exit_code == 2
    message = str(info.value)
    assert reason in message and "--hub" in message and repr(text) in message


def test_parse_host_and_format_address() -> None:
    assert parse_host("[::1]") == parse_host(" ::1 ") == "::1"
    assert parse_host("0.0.0.0") == "0.0.0.0"
    for bad in ("", "a b", "0.0.0.0:1500", "[::1]:5"):
        with pytest.raises(InvalidURL):
            parse_host(bad, what="--bind")
    assert format_address("::1", 8101) == "[::1]:8101"
    assert format_address("h", 1) == "h:1"
    assert parse_address(format_address("fe80::1%eth0", 5)) == ("fe80::1%eth0", 5)


@pytest.mark.parametrize(
    "url", ["/dev/ttyUSB0", "COM3", "tcp://[::1]:8101", "h:1", "loop://", "socket://h:1"]
)
def test_check_url_accepts_what_open_transport_opens(url: str) -> None:
    assert check_url(f" {url} ") == url


@pytest.mark.parametrize(
    ("url", "reason"),
    [
        ("bad url", "neither a serial port nor a TCP address"),
        ("robot", "neither a serial port nor a TCP address"),
        ("tcp://127.0.0.1:8101:9", "more than one ':'"),
        ("socket://h", "no port"),
        ("ftp://x", "unknown URL scheme 'ftp'"),
        ("  ", "empty"),
    ],
)
def test_check_url_refuses_without_opening(url: str, reason: str) -> None:
    with pytest.raises(InvalidURL, match=reason):
        check_url(url, what="pioneer")
    with pytest.raises(InvalidURL, match=reason):
        open_transport(url)


@needs_ipv6
@pytest.mark.parametrize("form", ["tcp://[::1]:{}", "[::1]:{}"])
def test_an_ipv6_literal_connects_to_a_server_on_ipv6_loopback(form: str) -> None:
    with socket.create_server(("::1", 0), family=socket.AF_INET6) as srv:
        port = srv.getsockname()[1]
        with open_transport(form.format(port)) as t:
            conn, _ = srv.accept()
            with conn:
                assert t.url == f"tcp://[::1]:{port}"
                conn.sendall(b"\xfa\xfb")
                assert _read_exactly(t, 2) == b"\xfa\xfb"
