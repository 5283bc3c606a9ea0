"""The recording proxy behind `robocli dump hub`, over real sockets: sessions come and go
without using up its slots."""

from __future__ import annotations

import threading
from collections.abc import Iterator

import pytest

from robocli import Hub
from robocli.analysis.ros4mat import DumpProxy, Message
from robocli.hub_server import HubServer
from tests.waiting import wait_for


@pytest.fixture(scope="module")
def server() -> Iterator[HubServer]:
    with HubServer(bind="127.0.0.1", port=0, sim=True).start() as srv:
        yield srv


def test_more_sessions_than_slots_one_after_another(server: HubServer) -> None:
    seen: list[Message] = []
    with DumpProxy(("127.0.0.1", server.port), seen.append, max_clients=2).start() as proxy:
        for _ in range(5):  # more than max_clients, each closed before the next
            with Hub.connect("127.0.0.1", proxy.port, timeout=5.0) as hub:
                hub.subscribe("adc", rate=100)
    names = [m.name for m in seen if m.direction == "c2s"]
    assert names.count("CONNECT") == 5 and names.count("SUBSCRIBE") >= 5


def test_a_client_that_closed_gives_its_slot_to_the_next_one(server: HubServer) -> None:
    """One slot; its client sends a request and closes while the proxy is still showing that
    request (its relaying thread has not seen the end yet), and the next client connects:
    it waits for the slot instead of being closed at once (a plain `make test` saw
    "connection reset" on the third of five sessions one after another)."""
    import socket

    from robocli.protocols import ros4mat as r4m

    shown, gate = threading.Event(), threading.Event()

    def on_message(m: Message) -> None:
        if m.direction == "c2s" and not shown.is_set():
            shown.set()
            gate.wait(10)  # the first request, held on its way

    links = server._server.links
    before = len(links())
    connect = r4m.encode_request(r4m.MsgType.CONNECT, {"protocol_version": 1, "compression": 0})
    with DumpProxy(("127.0.0.1", server.port), on_message, max_clients=1).start() as proxy:
        with socket.create_connection(("127.0.0.1", proxy.port), timeout=10) as first:
            first.sendall(connect)
            assert shown.wait(10)
        # closed; the next one: the proxy dials the hub for it, then finds the slot taken
        with socket.create_connection(("127.0.0.1", proxy.port), timeout=10) as second:
            wait_for(lambda: len(links()) >= before + 2, "the proxy dialling for the second")
            gate.set()
            second.sendall(connect)
            head = second.recv(r4m.HEADER_SIZE, socket.MSG_WAITALL)
            assert len(head) == r4m.HEADER_SIZE, "the second client was closed"
            assert r4m.Header.parse(head).type == r4m.MsgType.CONNECT_ACK


def test_the_shared_proxy_checks_its_framer_and_says_why_it_could_not_relay() -> None:
    """RecordingProxy (what DumpProxy is, with ros4mat): an unknown framer is refused when it
    is made; a client it cannot relay is closed, and ``upstream_error`` says why."""
    import socket

    from robocli.analysis.proxy import RecordingProxy

    with pytest.raises(ValueError, match="unknown protocol"):
        RecordingProxy(("127.0.0.1", 1), print, framer="nope")
    with socket.create_server(("127.0.0.1", 0)) as closed:
        dead = closed.getsockname()[1]  # a port nothing listens on, once closed
    with RecordingProxy(("127.0.0.1", dead), print, framer="sm-le").start() as proxy:
        assert proxy.upstream_error is None
        with socket.create_connection(("127.0.0.1", proxy.port), timeout=5.0) as client:
            client.settimeout(5.0)
            assert client.recv(16) == b""
        assert isinstance(proxy.upstream_error, ConnectionRefusedError)


def test_a_listen_address_in_use_or_unresolvable_is_a_typed_error(server: HubServer) -> None:
    """Where the proxy listens is the user's: a name that does not resolve or is not this
    machine's is a usage error (InvalidArgument), a port in use a TransportError; no
    OSError escapes (``dump hub`` and ``dump arm --listen`` both listen through it)."""
    from robocli.analysis.proxy import RecordingProxy
    from robocli.errors import InvalidArgument, TransportError

    upstream = ("127.0.0.1", server.port)
    with pytest.raises(TransportError, match=f"port {server.port} is in use"):
        DumpProxy(upstream, print, port=server.port)
    for bind in ("garbage.invalid", "256.1.1.1", "192.0.2.1"):  # the last: TEST-NET, not ours
        with pytest.raises(InvalidArgument, match="listen"):
            RecordingProxy(upstream, print, framer="sm-le", bind=bind)


def test_closing_lets_a_reply_in_flight_reach_the_client(server: HubServer) -> None:
    """``dump hub --count N`` closes the proxy on the Nth message, often the reply to the
    client's last request: that reply, read before the close, still reaches the client.
    The way that ends first (the client's, idle) must not cut the session under the way
    still relaying it (under load, the client got "link lost" instead of its reply)."""
    import select
    import socket
    import threading

    from robocli.analysis.proxy import RecordingProxy
    from robocli.protocols import ros4mat as r4m
    from tests.waiting import wait_for

    held, release = threading.Event(), threading.Event()
    replies: list[bytes] = []
    pumps: dict[str, threading.Thread] = {}

    def on_message(m: Message) -> None:
        pumps[m.direction] = threading.current_thread()
        if m.direction == "s2c":  # the CONNECT_ACK, read from the hub: held here
            replies.append(m.frame)
            held.set()
            assert release.wait(30)

    proxy = RecordingProxy(("127.0.0.1", server.port), on_message, framer="ros4mat").start()
    with socket.create_connection(("127.0.0.1", proxy.port), timeout=30) as client:
        client.sendall(r4m.encode_request(r4m.MsgType.CONNECT, bytes([r4m.PROTOCOL_VERSION, 0])))
        assert held.wait(30), "the hub's CONNECT_ACK never reached the proxy"
        closer = threading.Thread(target=proxy.close, args=(60.0,), daemon=True)
        closer.start()

        def cut() -> bool:  # the client's socket saw the end of the session
            readable = select.select([client], [], [], 0)[0]
            return bool(readable) and client.recv(1, socket.MSG_PEEK) == b""

        # the idle way sees the proxy closing and ends (its thread is gone), or, as before
        # the fix, cuts the whole session on its way out
        wait_for(lambda: cut() or not pumps["c2s"].is_alive(), "the client's way to end")
        release.set()
        got = b""
        while chunk := client.recv(65536):
            got += chunk
    closer.join(30)
    assert not closer.is_alive()
    assert got == replies[0] and r4m.decode(got).msg_type == r4m.MsgType.CONNECT_ACK
