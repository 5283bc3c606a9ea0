"""The recording proxy behind `robocli dump hub`, over real sockets: sessions come and go
without using up its slots."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from robocli import Hub
from robocli.devices.hub_tools import DumpProxy, Message
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
