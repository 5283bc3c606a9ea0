"""The recording proxy behind `robocli dump hub`, over real sockets: sessions come and go
without using up its slots."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from robocli import Hub
from robocli.devices.hub.tools import DumpProxy, Message
from robocli.hub import HubServer


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


def test_the_shared_proxy_checks_its_framer_and_says_why_it_could_not_relay() -> None:
    """RecordingProxy (what DumpProxy is, with ros4mat): an unknown framer is refused when it
    is made; a client it cannot relay is closed, and ``upstream_error`` says why."""
    import socket

    from robocli.devices.proxy import RecordingProxy

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
    from robocli.devices.proxy import RecordingProxy
    from robocli.errors import InvalidArgument, TransportError

    upstream = ("127.0.0.1", server.port)
    with pytest.raises(TransportError, match=f"port {server.port} is in use"):
        DumpProxy(upstream, print, port=server.port)
    for bind in ("garbage.invalid", "256.1.1.1", "192.0.2.1"):  # the last: TEST-NET, not ours
        with pytest.raises(InvalidArgument, match="listen"):
            RecordingProxy(upstream, print, framer="sm-le", bind=bind)
