"""The ros4mat front-end over real sockets: the original client's bytes, pulls, cursors."""

from __future__ import annotations

import socket
from typing import Any

import numpy as np
import pytest

from robocli.hub_server import HubServer
from robocli.protocols import ros4mat as r4m
from tests import paths

DATA = paths.DATA / "ros4mat"


def _session() -> dict[str, bytes]:
    """The original client's requests (docs/protocols/ros4mat.md section 7), one hex packet
    per line."""
    out = {}
    for line in (DATA / "original_client.hex").read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            name, hexa = line.split(None, 1)
            out[name] = bytes.fromhex(hexa.replace(" ", ""))
    return out


ORIGINAL = _session()


def _adc_times(msg: r4m.DecodedPacket) -> np.ndarray:
    return np.array([r["t"] for r in msg.body or []])


def test_original_client_bytes_are_served(hub: HubServer, client_factory: Any, wait: Any) -> None:
    c = client_factory()
    c.send(ORIGINAL["connect"])
    ack = c.recv()
    assert (ack.msg_type, ack.error, ack.size) == (r4m.MsgType.CONNECT_ACK, 0, 0)
    assert ack.client_id >= 1
    # the captured bytes carry client id 7: the connection, not the header, names the client
    c.send(ORIGINAL["subscribe_adc"])
    sub = c.recv()
    assert (sub.msg_type, sub.error) == (r4m.MsgType.SUBSCRIBE_ACK, 0)
    assert hub.sensors["adc"]["rate"] == 100 and hub.sensors["adc"]["batch_rate"] == 35

    def pulled() -> r4m.DecodedPacket | None:
        c.send(ORIGINAL["pull_adc"])
        msg = c.recv()
        return msg if msg.size >= 3 else None

    msg = wait(pulled, what="ADC samples")
    assert msg.msg_type == r4m.MsgType.ADC and msg.error == 0 and msg.compression_type == 0
    t = _adc_times(msg)
    assert np.allclose(np.diff(t), 0.01, rtol=1e-3)
    assert msg.packet_timestamp >= t[-1]
    assert hub.clients[0].subscriptions == {"adc": 100}
    c.send(ORIGINAL["digital_out_1010"])  # no reply, as the original client expects
    c.send(ORIGINAL["unsubscribe_adc"])  # no reply either
    c.send(ORIGINAL["subscribe_adc_silent"])  # nobody is subscribed now: an error reply
    err = c.recv()
    assert err.msg_type == r4m.MsgType.SUBSCRIBE_ACK and err.error and "nobody" in err.error_text
    assert hub.sensors["adc"]["digital_out"] == [1, 0, 1, 0]
    assert not hub.sensors["adc"]["active"]
    c.send(ORIGINAL["quit"])
    assert c.sock.recv(1) == b""
    wait(lambda: not hub.clients, what="the client to be forgotten")


def test_pull_without_subscribing_is_a_size_0_reply(client_factory: Any) -> None:
    """The original server answered a pull of a sensor the client is not subscribed to with
    an empty reply, which lab scripts read as an 8x0 matrix; so does the hub."""
    c = client_factory()
    c.send(ORIGINAL["connect"])
    cid = c.recv().client_id
    pull = bytearray(ORIGINAL["pull_adc"])
    pull[2:6] = cid.to_bytes(4, "little")
    c.send(bytes(pull))
    raw = c.recv_raw()
    head = r4m.Header.parse(raw)
    assert len(raw) == r4m.HEADER_SIZE
    assert (head.type, head.error, head.size, head.uncompress_size) == (0x20, 0, 0, 0)
    for sensor in ("imu", "gps", "camera", "laser", "depth", "stereo", "sysinfo", "battery"):
        reply = c.pull(sensor)
        assert (reply.error, reply.size) == (0, 0), (sensor, reply)


def test_empty_pull_is_a_size_0_reply(client_factory: Any) -> None:
    c = client_factory(connected=True)
    assert c.subscribe("gps", {"freq_acquisition": 1, "freq_send": 1}).error == 0
    c.pull("gps")  # the first fix, if already there
    raw = None
    for _ in range(3):
        c.send(r4m.encode_request("gps", client_id=c.client_id))
        raw = c.recv_raw()
        if r4m.Header.parse(raw).size == 0:
            break
    assert raw is not None and len(raw) == r4m.HEADER_SIZE
    head = r4m.Header.parse(raw)
    assert (head.type, head.size, head.uncompress_size, head.error) == (0x23, 0, 0, 0)
    assert head.packet_timestamp > 0


def test_many_clients_have_independent_cursors(
    hub: HubServer, client_factory: Any, wait: Any
) -> None:
    clients = [client_factory() for _ in range(4)]
    for c in clients:
        c.connect()
    params = {"freq_acquisition": 200, "freq_send": 50}
    assert clients[0].subscribe("imu", params, buffer=2000).error == 0
    for c in clients[1:]:
        assert c.subscribe("imu", silent=True).error == 0
    ring = hub.hub.channels["imu"].ring
    seen: list[list[float]] = [[] for _ in clients]
    # client k pulls every (k+1)-th round: each sees every sample once, in order, no gap
    for rnd in range(1, 9):
        start = ring.pushed
        wait(lambda start=start: ring.pushed >= start + 4, what="new samples")
        for k, c in enumerate(clients):
            if rnd % (k + 1) == 0:
                seen[k] += [r["t"] for r in c.pull("imu").body or []]
    for s in seen:
        t = np.array(s)
        assert len(t) > 5 and np.allclose(np.diff(t), 1 / 200, rtol=1e-3)
    last = min(s[-1] for s in seen)
    firsts = [s[0] for s in seen]
    common = [{x for x in s if max(firsts) <= x <= last} for s in seen]
    assert all(c == common[0] for c in common) and len(common[0]) > 5
    assert sum(ci.dropped for ci in hub.clients) == 0


def test_overflow_drops_oldest_and_counts(hub: HubServer, client_factory: Any, wait: Any) -> None:
    c = client_factory(connected=True)
    assert (
        c.subscribe(
            "adc", {"freq_acquisition": 1000, "freq_send": 100, "channels": 255}, buffer=10
        ).error
        == 0
    )
    wait(lambda: hub.clients[0].dropped > 50, what="samples to be dropped")
    msg = c.pull("adc")
    t = _adc_times(msg)
    assert msg.size == 10 and np.allclose(np.diff(t), 1e-3, rtol=1e-3)
    assert msg.packet_timestamp - t[-1] < 0.5  # the newest were kept
    assert hub.clients[0].dropped > 50


@pytest.mark.parametrize("compress", [False, True])
def test_compression_per_connection(client_factory: Any, wait: Any, compress: bool) -> None:
    c = client_factory()
    c.connect(compress=compress)
    c.subscribe("adc", {"freq_acquisition": 500, "freq_send": 50, "channels": 0x0F})
    msg = wait(lambda: (m := c.pull("adc")).size and m, what="samples")
    assert msg.compression_type == (1 if compress else 0)
    chans = np.array([r["channels"] for r in msg.body])
    assert chans.shape == (msg.size, 8) and (chans[:, 4:] == 0).all() and (chans[:, :4] != 0).all()


def test_silent_subscribe_joins_current_settings(
    hub: HubServer, client_factory: Any, wait: Any
) -> None:
    a, b = client_factory(connected=True), client_factory(connected=True)
    assert b.subscribe("imu", silent=True).error  # nobody to join yet
    assert a.subscribe("imu", {"freq_acquisition": 250, "freq_send": 25}, buffer=77).error == 0
    assert b.subscribe("imu", silent=True).error == 0
    infos = {ci.id: ci for ci in hub.clients}
    assert infos[b.client_id].subscriptions == {"imu": 77}
    msg = wait(lambda: (m := b.pull("imu")).size > 2 and m, what="samples")
    assert np.allclose(np.diff([r["t"] for r in msg.body]), 1 / 250, rtol=1e-3)


def test_reconnect_with_client_id_keeps_buffers(hub: HubServer, raw: Any, wait: Any) -> None:
    a = raw(hub.port)
    cid = a.connect()
    a.subscribe("adc", {"freq_acquisition": 200, "freq_send": 20, "channels": 255}, buffer=1000)
    first = wait(lambda: (m := a.pull("adc")).size and m, what="samples")
    a.close()
    wait(lambda: not hub.clients[0].connected, what="the hub to see the disconnection")
    gone_at = hub.hub.clock()
    ring = hub.hub.channels["adc"].ring
    start = ring.pushed
    wait(lambda: ring.pushed >= start + 40, what="samples while the client is away")
    b = raw(hub.port)
    assert b.connect(client_id=cid) == cid
    msg = b.pull("adc")
    t = _adc_times(msg)
    assert t[0] == pytest.approx(_adc_times(first)[-1] + 1 / 200)  # nothing lost meanwhile
    assert t[-1] > gone_at + 0.1  # acquired while it was away
    b.close()


def test_a_live_client_id_is_not_taken_over_a_new_one_is_given(hub: HubServer, raw: Any) -> None:
    """CONNECT naming a connected client's id gets a new id (the original client sends its
    old id again after ``close``, and adopts the one in CONNECT_ACK), never that client."""
    a, b = raw(hub.port), raw(hub.port)
    cid = a.connect()
    assert a.subscribe("imu", {"freq_acquisition": 100, "freq_send": 20}).error == 0
    b.send(r4m.encode_request(r4m.MsgType.CONNECT, b"\x03\x00", client_id=cid))
    ack = b.recv()
    assert (ack.msg_type, ack.error) == (r4m.MsgType.CONNECT_ACK, 0), ack
    assert ack.client_id not in (0, cid)
    infos = {c.id: c for c in hub.clients}
    assert infos[cid].connected and infos[cid].subscriptions == {"imu": 100}
    assert infos[ack.client_id].subscriptions == {}
    assert a.pull("imu").error == 0
    a.close()
    b.close()


def test_original_client_close_then_connect(raw: Any, wait: Any) -> None:
    """The original client's ``close`` (QUIT) then an immediate ``connect`` carries the old
    id while the hub may not have handled the QUIT yet: every CONNECT is answered with an
    id (a new one), on a hub with room for one client only."""
    with HubServer(port=0, max_clients=1) as srv:
        cid = 0
        for _ in range(30):
            c = raw(srv.port)
            connect = bytearray(ORIGINAL["connect"])
            connect[2:6] = cid.to_bytes(4, "little")  # it never resets its id
            c.send(bytes(connect))
            ack = c.recv()
            assert (ack.msg_type, ack.error) == (r4m.MsgType.CONNECT_ACK, 0), ack.error_text
            cid = ack.client_id
            c.send(r4m.encode_request(r4m.MsgType.QUIT, client_id=cid))
            c.close()
        wait(lambda: not srv.clients, what="every client to be forgotten")


def test_quit_and_errors(hub: HubServer, client_factory: Any) -> None:
    c = client_factory()
    err = c.request("adc")  # no CONNECT yet
    assert err.msg_type == r4m.MsgType.ADC and err.error and "CONNECT" in err.error_text
    c.connect()
    empty = c.request("imu")  # not subscribed: an empty reply, as the original server's
    assert (empty.msg_type, empty.error, empty.size) == (r4m.MsgType.IMU, 0, 0)
    head = {"sensor": 0x28, "silent": 0, "buffer_size": 1, "params_size": 30}
    err = c.request(r4m.MsgType.SUBSCRIBE, r4m.Subscribe.build(head) + bytes(30))
    assert err.msg_type == r4m.MsgType.SUBSCRIBE_ACK and "not served" in err.error_text
    bad = c.subscribe("adc", {"freq_acquisition": 60000, "freq_send": 1, "channels": 1})
    assert bad.error and "freq_acquisition" in bad.error_text


def test_connection_limit(raw: Any) -> None:
    with HubServer(port=0, max_clients=2) as srv:
        a, b = raw(srv.port), raw(srv.port)
        a.connect()
        b.connect()
        c = raw(srv.port)  # refused in ros4mat (a CONNECT_ACK error reply)
        reply = c.request(r4m.MsgType.CONNECT, bytes([r4m.PROTOCOL_VERSION, 0]))
        assert reply.error and "hub full" in reply.error_text
        assert (
            a.subscribe("adc", {"freq_acquisition": 10, "freq_send": 10, "channels": 1}).error == 0
        )
        for x in (a, b, c):
            x.close()


def test_bind_all_interfaces_warns() -> None:
    srv = HubServer(bind="0.0.0.0", port=0)
    try:
        assert "ALL interfaces" in srv.exposure_warning()
        assert "NO authentication" in srv.exposure_warning()
    finally:
        srv.close()
    assert HubServer(port=0).exposure_warning() is None


def test_closed_client_socket_leaves_server_serving(hub: HubServer, raw: Any) -> None:
    s = socket.create_connection(("127.0.0.1", hub.port))
    s.sendall(ORIGINAL["connect"][:10])
    s.close()
    c = raw(hub.port)
    assert c.connect() >= 1
    c.close()


SUBSCRIBES = {
    "subscribe_imu": ("imu", {"rate": 50, "batch_rate": 22}),
    "subscribe_gps": ("gps", {"rate": 1, "batch_rate": 1}),
    "subscribe_ordinateur": ("sysinfo", {"rate": 2}),
    "subscribe_hokuyo": ("laser", {"rate": 10}),
    "subscribe_camera": ("camera", {"rate": 15, "width": 640, "height": 480, "quality": 0}),
    "subscribe_kinect": ("depth", {"rate": 30, "width": 640, "height": 480}),
    "subscribe_camera_stereo": ("stereo", {"rate": 15, "width": 320, "height": 240}),
}


@pytest.mark.parametrize("vector", sorted(SUBSCRIBES))
def test_original_client_subscribes_to_every_sensor(
    hub: HubServer, client_factory: Any, wait: Any, vector: str
) -> None:
    name, settings = SUBSCRIBES[vector]
    c = client_factory()
    c.send(ORIGINAL["connect_zlib"])
    assert c.recv().msg_type == r4m.MsgType.CONNECT_ACK
    c.send(ORIGINAL[vector])
    ack = c.recv()
    assert (ack.msg_type, ack.error) == (r4m.MsgType.SUBSCRIBE_ACK, 0), ack
    got = hub.sensors[name]
    assert {k: got[k] for k in settings} == settings
    buffer = r4m.SubscribeRequest.parse(ORIGINAL[vector][r4m.HEADER_SIZE :]).buffer_size
    assert hub.clients[0].subscriptions == {name: buffer}
    kind = ORIGINAL[vector][r4m.HEADER_SIZE]
    pull = r4m.encode_request(kind)  # client id 0: the connection names the client
    c.send(pull)
    reply = c.recv()
    assert reply.msg_type == kind and reply.error == 0
    if reply.size:
        assert reply.compression_type == 1  # zlib asked at CONNECT


def test_reply_with_partly_filled_blobs_decodes() -> None:
    """JPEG frames fill only part of their slot: the reply carries each at its own size."""
    from robocli.hub_server.frontends.ros4mat import pull_body
    from robocli.hub_server.registry import Pulled
    from robocli.hub_server.sources import StereoSource

    src = StereoSource()
    src.configure({"fps": 10, "width": 32, "height": 24})
    t = np.array([1.0, 2.0])
    rec = src.sample(t)
    sizes = [[100, 7], [2304, 1]]
    for i in range(2):
        for j in range(2):
            rec["info"][i, j]["size_data"] = sizes[i][j]
    body = pull_body(Pulled(t, rec, src))
    msg = r4m.decode(r4m.encode_packet(r4m.MsgType.WEBCAM_STEREO, bytes(body), size=2))
    images = msg.body["images"]
    assert [len(x) for x in images] == [100, 7, 2304, 1]
    assert images[0] == rec["blob0"][0, :100].tobytes()
    assert images[3] == rec["blob1"][1, :1].tobytes()
    assert [i["t"] for i in msg.body["infos"]] == [1.0, 1.0, 2.0, 2.0]


def test_detached_client_is_forgotten_after_its_ttl(raw: Any, wait: Any) -> None:
    with HubServer(port=0, detached_ttl=0.3) as srv:
        c = raw(srv.port)
        c.connect()
        c.subscribe("imu", {"freq_acquisition": 100, "freq_send": 20})
        c.close()
        wait(lambda: srv.clients and not srv.clients[0].connected, what="detached")
        wait(lambda: not srv.clients, what="the client forgotten")
        assert not srv.sensors["imu"]["active"]  # its sensor stopped with it


def test_a_bigger_buffer_or_a_bad_setting_does_not_disturb_others(
    hub: HubServer, client_factory: Any, wait: Any
) -> None:
    a, b = client_factory(connected=True), client_factory(connected=True)
    params = {"freq_acquisition": 100, "freq_send": 50, "channels": 255}
    assert a.subscribe("adc", params, buffer=500).error == 0
    ring = hub.hub.channels["adc"].ring
    wait(lambda: ring.pushed > 20, what="samples")
    assert b.subscribe("adc", params, buffer=60000).error == 0  # same settings, huge buffer
    bad = b.subscribe("adc", {**params, "freq_acquisition": 60000})
    assert bad.error and hub.sensors["adc"]["rate"] == 100  # refused, nothing changed
    msg = a.pull("adc")
    assert msg.size > 20  # a's unread samples survived b's requests
    infos = {c.id: c for c in hub.clients}
    assert infos[b.client_id].subscriptions["adc"] == ring.capacity  # clamped
    assert infos[a.client_id].dropped == 0
