"""With a token, a peer without it cannot take the hub's places from those who have it
(issue 21, point 3: 64 plain CONNECTs took all 64 places and token holders got "hub full";
connected clients had no idle limit and the per-address limit counted only pending ones)."""

from __future__ import annotations

import time
from typing import Any

from robocli.hub_server import HubServer
from robocli.protocols import ros4mat as r4m
from tests.peers import closed_by_peer

TOKEN = b"lab-token"


def plain_connect(raw: Any, port: int) -> tuple[Any, r4m.DecodedPacket]:
    """A CONNECT without the token, and its reply (the socket kept open, idle)."""
    c = raw(port)
    return c, c.request(r4m.MsgType.CONNECT, bytes([r4m.PROTOCOL_VERSION, 0]))


def test_plain_connects_cannot_take_the_places_of_token_holders(raw: Any) -> None:
    """12 CONNECTs without the token from one address get at most the places not kept for
    token holders and at most ``max_per_address``; then 8 token holders (as many as there
    are places) all connect, taking the places of the idle ones without the token."""
    with HubServer(port=0, token=TOKEN, max_clients=8, max_per_address=4) as srv:
        plain = [plain_connect(raw, srv.port) for _ in range(12)]
        admitted = [c for c, ack in plain if ack.error == 0]
        refused = [ack for _c, ack in plain if ack.error != 0]
        assert len(admitted) == 4  # per address, within the 8 - 2 reserved
        assert refused and all("without the token" in (a.error_text or "") for a in refused)
        holders = []
        for _ in range(8):
            c = raw(srv.port)
            c.connect(token=TOKEN)  # asserts a CONNECT_ACK without error
            holders.append(c)
        assert all(closed_by_peer(c.sock) for c in admitted)
        assert srv.places.evicted == 4
        for c in holders:
            assert c.subscribe("imu", {"freq_acquisition": 50, "freq_send": 10}).error == 0
        for c in [*holders, *(c for c, _ack in plain)]:
            c.close()


def test_an_idle_client_without_the_token_loses_its_place(raw: Any, wait: Any) -> None:
    with HubServer(port=0, token=TOKEN, max_clients=4, idle_timeout=0.5) as srv:
        holder = raw(srv.port)
        holder.connect(token=TOKEN)
        stranger, ack = plain_connect(raw, srv.port)
        assert ack.error == 0
        opened = time.monotonic()
        assert closed_by_peer(stranger.sock)
        assert srv.places.expired == 1
        wait(lambda: time.monotonic() > opened + 4 * srv.places.idle_timeout, what="idle")
        imu = {"freq_acquisition": 50, "freq_send": 10}
        assert holder.subscribe("imu", imu).error == 0  # a token holder keeps its place
        for c in (holder, stranger):
            c.close()
