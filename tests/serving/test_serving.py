"""The shared serving layer (``robocli.serving.server``) over real sockets and a real pty.

An echo session stands for a robot: every complete ARCOS frame comes back as it was sent.
"""

from __future__ import annotations

import contextlib
import os
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from robocli.errors import TransportError
from robocli.protocols import arcos
from robocli.protocols.common import REFUSAL_PREFIX, find_refusal
from robocli.serving.server import BUSY_REASON, Link, Server
from robocli.serving.ticker import Ticker
from tests.waiting import wait_for

pytestmark = pytest.mark.timeout(30)


class Echo:
    """Echoes each frame; a frame whose payload is ``b"boom"`` raises (a buggy session)."""

    def __init__(self, link: Link, log: list[tuple[str, Any]]) -> None:
        self.link, self.log = link, log
        log.append(("open", link.name))

    def on_frame(self, frame: bytes, now: float) -> bytes | None:
        if frame[3:-2] == b"boom":
            raise RuntimeError("session bug")
        self.log.append(("frame", frame))
        return frame

    def on_close(self) -> None:
        self.log.append(("close", self.link.name))


@pytest.fixture
def make_server() -> Iterator[Callable[..., tuple[Server, list[tuple[str, Any]]]]]:
    servers: list[Server] = []

    def make(**kw: Any) -> tuple[Server, list[tuple[str, Any]]]:
        events: list[tuple[str, Any]] = []
        kw.setdefault("protocol", "arcos")
        server = Server(lambda link: Echo(link, events), name="echo", **kw)
        servers.append(server)
        server.serve_tcp()
        return server, events

    yield make
    for s in servers:
        s.close()


def dial(server: Server, *, rcvbuf: int | None = None) -> socket.socket:
    assert server.url is not None
    host, port = server.url.removeprefix("tcp://").rsplit(":", 1)
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    if rcvbuf is not None:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
    sock.settimeout(10.0)
    sock.connect((host, int(port)))
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return sock


def read_exactly(sock: socket.socket, n: int) -> bytes:
    buf = b""
    while len(buf) < n:
        chunk = sock.recv(n - len(buf))
        if not chunk:
            raise ConnectionError(f"closed after {buf!r}")
        buf += chunk
    return buf


def read_to_eof(sock: socket.socket, limit: float = 2.0) -> bytes:
    buf = b""
    end = time.monotonic() + limit
    while time.monotonic() < end:
        try:
            chunk = sock.recv(4096)
        except ConnectionResetError:
            break
        if not chunk:
            break
        buf += chunk
    return buf


def echo_ok(sock: socket.socket, payload: bytes = b"\x00") -> None:
    f = arcos.frame(payload)
    sock.sendall(f)
    assert read_exactly(sock, len(f)) == f


def server_threads(name: str = "echo") -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith(f"{name}-")]


def test_request_reply_inline(make_server: Any) -> None:
    server, events = make_server()
    sock = dial(server)
    for i in range(50):
        echo_ok(sock, bytes((i,)) * (i % 7 + 1))
    sock.sendall(arcos.frame(b"\x01") + arcos.frame(b"\x02"))  # two frames, one segment
    assert read_exactly(sock, 12) == arcos.frame(b"\x01") + arcos.frame(b"\x02")
    wait_for(
        lambda: server.stats().bytes_out == 459,
        "the 459 bytes counted",
    )  # counted just after the write
    s = server.stats()
    assert (s.frames, s.bytes_in, s.dropped_bytes) == (52, 459, 0)
    sock.close()
    wait_for(lambda: not server.links(), "no link left")
    assert events[0][0] == "open" and events[-1][0] == "close"


def test_limit_refuses_with_a_reason_the_client_can_show(make_server: Any) -> None:
    server, _ = make_server(max_clients=1)
    first = dial(server)
    echo_ok(first)
    second = dial(server)
    second.sendall(arcos.frame(b"\x00") * 3)  # unread input must not turn the line into a reset
    got = read_to_eof(second)
    assert got == REFUSAL_PREFIX + BUSY_REASON.encode() + b"\n"
    assert find_refusal(got) == BUSY_REASON
    echo_ok(first)  # the holder is undisturbed
    assert (server.accepted, server.refused, len(server.links())) == (1, 1, 1)
    first.close()
    wait_for(lambda: not server.links(), "no link left")
    third = dial(server)  # the place is free again
    echo_ok(third)


def test_limit_of_several_clients(make_server: Any) -> None:
    server, _ = make_server(max_clients=3)
    socks = [dial(server) for _ in range(3)]
    for s in socks:
        echo_ok(s)
    assert find_refusal(read_to_eof(dial(server))) == BUSY_REASON
    for s in socks:
        echo_ok(s)


def test_oversize_frame_is_dropped_and_counted(make_server: Any) -> None:
    server, events = make_server(max_frame=20)
    sock = dial(server)
    big = arcos.frame(b"\x10" * 40)  # 45 bytes: over the limit
    sock.sendall(big + arcos.frame(b"\x05ok"))
    assert read_exactly(sock, 8) == arcos.frame(b"\x05ok")
    s = server.stats()
    assert s.oversize == 1 and s.dropped_bytes >= len(big) and s.frames == 1
    assert [e for e in events if e[0] == "frame"] == [("frame", arcos.frame(b"\x05ok"))]


def test_partial_frame_is_abandoned_after_the_byte_timeout(make_server: Any) -> None:
    server, _ = make_server(byte_timeout=2.0)  # longer than a loaded machine's stall
    sock = dial(server)
    # a header announcing 255 bytes that never come, then a real frame caught inside it
    sock.sendall(b"\xfa\xfb\xff" + arcos.frame(b"\x07"))
    sock.settimeout(0.15)
    with pytest.raises(TimeoutError):
        sock.recv(64)  # held hostage while the partial frame may still complete
    sock.settimeout(30.0)
    assert read_exactly(sock, 6) == arcos.frame(b"\x07")
    s = server.stats()
    assert s.abandoned == 1 and s.dropped_bytes == 3 and s.frames == 1
    echo_ok(sock)  # and the link goes on


def test_a_session_that_raises_drops_only_its_link(
    make_server: Any, caplog: pytest.LogCaptureFixture
) -> None:
    server, events = make_server(max_clients=2)
    good, bad = dial(server), dial(server)
    bad.sendall(arcos.frame(b"boom"))
    assert read_to_eof(bad) == b""
    wait_for(lambda: len(server.links()) == 1, "one link")
    echo_ok(good)
    assert server.stats().session_errors == 1
    assert "session failed" in caplog.text and "RuntimeError: session bug" in caplog.text
    assert sum(1 for e in events if e[0] == "close") == 1


def test_a_client_that_stops_reading_is_dropped_without_blocking_the_ticker(
    make_server: Any,
) -> None:
    server, _ = make_server(max_clients=2, send_timeout=0.4, max_backlog=1 << 24)
    chunk = arcos.frame(b"\x20" * 200) * 256  # ~52 KB per tick
    longest = [0.0]

    def push(now: float) -> None:
        t0 = time.monotonic()
        for link in server.links():
            link.send(chunk)
        longest[0] = max(longest[0], time.monotonic() - t0)

    reader = dial(server)
    stuck = dial(server, rcvbuf=4096)  # never reads
    wait_for(lambda: len(server.links()) == 2, "two links")
    received = [0]
    stop = threading.Event()

    def drain() -> None:
        while not stop.is_set():
            try:
                received[0] += len(reader.recv(1 << 20))
            except (TimeoutError, OSError):
                return

    t = threading.Thread(target=drain, daemon=True)
    t.start()
    ticker = Ticker(0.01, push, "pusher")
    ticker.start()
    try:
        wait_for(lambda: len(server.links()) == 1, "one link", timeout=15.0)
        ticks, got = ticker.ticks, received[0]
        wait_for(
            lambda: ticker.ticks > ticks + 10 and received[0] > got,
            "ten more ticks and more bytes received",
            timeout=3.0,
        )
    finally:
        ticker.close()
        stop.set()
    assert server.stats().tx_dropped > 0  # the stuck client's backlog was discarded
    assert longest[0] < 0.2  # a blocked send would have held the ticker send_timeout (0.4 s)
    assert ticker.errors == 0
    reader.close()
    stuck.close()


def test_close_joins_every_thread(make_server: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    from robocli.serving import server as serving

    # a refused client that does not hang up keeps its thread for 60 s, not 0.5 s, so that
    # the thread is still there when close() comes, however late a loaded machine is
    monkeypatch.setattr(serving, "REFUSE_LINGER_S", 60.0)
    server, events = make_server(max_clients=2)
    a, b = dial(server), dial(server)
    echo_ok(a)
    b.sendall(b"\xfa\xfb\x10\x01")  # mid-frame
    refused = dial(server)  # lingering refusal thread
    wait_for(
        lambda: len(server.links()) == 2 and server.refused == 1,
        "two links and one refused",
    )
    line = b""  # read before close(): close() may drop a line not yet sent ("or is lost")
    refused.settimeout(30.0)
    while not line.endswith(b"\n"):
        chunk = refused.recv(4096)
        assert chunk, line
        line += chunk
    assert find_refusal(line) == BUSY_REASON
    assert len(server_threads()) >= 3
    server.close()
    assert server_threads() == []
    assert read_to_eof(a) == b"" and read_to_eof(b) == b""
    assert read_to_eof(refused) == b""
    assert sum(1 for e in events if e[0] == "close") == 2
    server.close()  # idempotent
    with pytest.raises(TransportError):
        server.serve_tcp()


def test_two_servers_in_one_process_are_independent(make_server: Any) -> None:
    one, ev1 = make_server()
    two, ev2 = make_server()
    assert one.url != two.url
    a, b = dial(one), dial(two)
    echo_ok(a, b"\x01")
    echo_ok(b, b"\x02")
    one.close()
    echo_ok(b, b"\x03")
    assert [e[1] for e in ev1 if e[0] == "frame"] == [arcos.frame(b"\x01")]
    assert [e[1] for e in ev2 if e[0] == "frame"] == [arcos.frame(b"\x02"), arcos.frame(b"\x03")]


def test_bad_arguments_and_busy_port(make_server: Any) -> None:
    with pytest.raises(ValueError):
        Server(lambda link: Echo(link, []), protocol="nope")
    with pytest.raises(ValueError):
        Server(lambda link: Echo(link, []), protocol="arcos", max_clients=0)
    server, _ = make_server()
    assert server.url is not None
    port = int(server.url.rsplit(":", 1)[1])
    other = Server(lambda link: Echo(link, []), protocol="arcos")
    with pytest.raises(TransportError, match=f"port {port} is in use"):
        other.serve_tcp(port=port)
    other.close()
    with pytest.raises(TransportError, match="already serves"):
        server.serve_tcp()


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pty")
def test_pty_link_echoes_and_abandons_partials() -> None:
    import tty

    events: list[tuple[str, Any]] = []
    server = Server(lambda link: Echo(link, events), protocol="arcos", name="ptyecho",
                    byte_timeout=0.2)  # fmt: skip
    try:
        path = server.serve_pty()
        fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(fd)
        try:
            os.write(fd, b"\xfa\xfb\xff" + arcos.frame(b"\x09"))
            got = b""
            end = time.monotonic() + 3.0
            while len(got) < 6 and time.monotonic() < end:
                got += os.read(fd, 64)
            assert got == arcos.frame(b"\x09")
            assert server.stats().abandoned == 1
        finally:
            os.close(fd)
    finally:
        server.close()
    assert server_threads("ptyecho") == []
    assert events[-1][0] == "close"


@contextlib.contextmanager
def busy_cpu() -> Iterator[None]:
    """Every core busy with a spinning process (ended by its handle) for the block."""
    spinners = [
        subprocess.Popen([sys.executable, "-c", "while True: pass"], stdin=subprocess.DEVNULL)
        for _ in range(os.cpu_count() or 2)
    ]
    try:
        yield
    finally:
        for p in spinners:
            p.kill()
        for p in spinners:
            p.wait(10)


def test_a_client_that_closed_does_not_hold_its_place_against_its_reconnect(
    make_server: Any,
) -> None:
    """Connect, close, reconnect at once, 100 times, with every core busy: the old link's
    thread may not have seen the end of its stream yet, but a peer that has closed does not
    hold the one place (it was refused "robot busy" 44 times in 100)."""
    server, events = make_server(max_clients=1)
    with busy_cpu():
        for i in range(100):
            sock = dial(server)
            sock.settimeout(10.0)
            f = arcos.frame(bytes((i % 256,)))
            sock.sendall(f)
            got = read_exactly(sock, len(f))
            assert got == f, (i, got)  # not the refusal line
            sock.close()
    assert server.refused == 0
    wait_for(lambda: not server.links(), "no link left")
    assert sum(1 for e in events if e[0] == "close") == 100


def test_a_pioneer_reconnecting_at_once_is_not_busy() -> None:
    """The same through the Pioneer simulator (one client at a time)."""
    from robocli.sim.pioneer.server import PioneerSim

    with PioneerSim() as sim, busy_cpu():
        url = sim.serve_tcp(port=0)
        host, port = url.removeprefix("tcp://").rsplit(":", 1)
        for i in range(50):
            with socket.create_connection((host, int(port)), timeout=10.0) as sock:
                sock.sendall(arcos.frame(b"\x00"))  # SYNC0
                got = read_exactly(sock, 3)
                assert got[:2] == arcos.SYNC, (i, got + read_to_eof(sock))
