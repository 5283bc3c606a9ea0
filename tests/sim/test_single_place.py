"""A simulator's single place cannot be held by an idle connection (issue 21, point 7: one
silent TCP connection held ``sim pioneer`` and ``sim laser`` for 15 s or more). A client that
completed its protocol's handshake keeps the place."""

from __future__ import annotations

import socket
import time
from typing import Any

import pytest

from robocli.devices.laser import Laser
from robocli.devices.pioneer import Pioneer
from robocli.protocols.common import find_refusal
from robocli.sim.hokuyo.server import HokuyoSim
from robocli.sim.pioneer.server import PioneerSim
from tests.peers import closed_by_peer
from tests.waiting import wait_for

HANDSHAKE_S = 0.5
DEADLINE_S = 30.0


def dial(url: str) -> socket.socket:
    host, port = url.removeprefix("tcp://").rsplit(":", 1)
    return socket.create_connection((host, int(port)), timeout=5.0)


@pytest.mark.parametrize("kind", ["pioneer", "laser"])
def test_an_idle_connection_loses_the_place_and_a_client_gets_it(kind: str) -> None:
    sim: Any = (PioneerSim(handshake_s=HANDSHAKE_S) if kind == "pioneer"
                else HokuyoSim(handshake_s=HANDSHAKE_S))  # fmt: skip
    with sim:
        url = sim.serve_tcp("127.0.0.1", 0)
        idle = dial(url)
        try:
            assert closed_by_peer(idle), "the idle connection still holds the place"
        finally:
            idle.close()
        client: Any = Pioneer.connect(url) if kind == "pioneer" else Laser.connect(url)
        with client:
            server = sim._server if kind == "laser" else sim._servers["tcp"]
            link = server.links()[0]
            wait_for(lambda: time.monotonic() > link.opened + 3 * HANDSHAKE_S,
                     "the client's link past the deadline")  # fmt: skip
            assert link.alive and link.established  # a client past its handshake keeps it
            late = dial(url)
            try:
                late.settimeout(DEADLINE_S)
                assert find_refusal(late.recv(4096)) is not None
            finally:
                late.close()
