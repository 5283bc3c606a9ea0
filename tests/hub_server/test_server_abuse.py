"""Abuse: malformed input next to a streaming client, tokens, slow clients, memory."""

from __future__ import annotations

import os
import random
import socket
import struct
import threading
import time
import tracemalloc
from typing import Any

import numpy as np

from robocli.hub_server import HubServer
from robocli.protocols import ros4mat as r4m

ADC_FAST = {"freq_acquisition": 500, "freq_send": 50, "channels": 255}


def _header(kind: int, size: int, usize: int, csize: int, ctype: int = 0, error: int = 0) -> bytes:
    return r4m.Header.build(
        {"type": kind, "error": error, "client_id": 0, "size": size, "uncompress_size": usize,
         "compress_size": csize, "compression_type": ctype, "packet_timestamp": 0.0}
    )  # fmt: skip


def test_malformed_input_does_not_disturb_a_streaming_client(
    hub: HubServer, client_factory: Any
) -> None:
    good, bad = client_factory(), client_factory()
    good.connect()
    assert good.subscribe("adc", ADC_FAST, buffer=5000).error == 0
    times: list[float] = []
    stop = threading.Event()
    failures: list[BaseException] = []

    def stream() -> None:
        try:
            while not stop.is_set():
                times.extend(r["t"] for r in good.pull("adc").body or [])
        except BaseException as exc:  # reported by the main thread
            failures.append(exc)

    thread = threading.Thread(target=stream)
    thread.start()
    try:
        bad.connect()
        rng = random.Random(9)
        noise = client_factory(connected=True)
        noise.send(bytes(rng.randrange(256) for _ in range(5000)))  # garbage: closed
        assert noise.sock.recv(64) == b""
        replies = []
        for frame, want in [
            (_header(0x2F, 0, 0, 0), 0x2F),  # unknown id
            (_header(0x0A, 1, 3, 3) + b"abc", 0x0A),  # unknown command
            (_header(0x07, 1, 3, 3) + b"abc", 0x17),  # truncated SERIAL_OPEN (robocli's)
            (_header(0x03, 1, 4, 2, ctype=1) + b"\x78\x9c", 0x13),  # compressed request
            (_header(0x03, 1, 3, 3) + b"\x20\x00\x01", 0x13),  # truncated SUBSCRIBE
            (
                _header(0x03, 1, 12, 12) + bytes([0x20, 0]) + struct.pack("<II", 9, 2) + b"zz",
                0x13,
            ),  # wrong params size
            (_header(0x20, 1, 2, 2) + b"zz", 0x20),  # a pull with a body
            (_header(0x01, 1, 1, 1) + b"\x03", 0x11),  # short CONNECT
            (_header(0x21, 0, 5, 5, error=1) + b"oops\0", 0x21),  # an error from a client
        ]:
            bad.send(frame)
            reply = bad.recv()
            replies.append(reply)
            assert reply.error and reply.msg_type == want, (frame.hex(), reply)
        assert bad.connect() >= 1  # still served
        end = time.monotonic() + 0.3
        while time.monotonic() < end and not failures:  # new connections of garbage
            junk = client_factory()
            junk.send(os.urandom(64))
    finally:
        stop.set()
        thread.join(10)
    assert not failures
    t = np.array(times)
    assert len(t) > 50 and np.allclose(np.diff(t), 1 / 500, rtol=1e-3)  # not one lost
    info = {c.id: c for c in hub.clients}[good.client_id]
    assert info.dropped == 0


def test_idle_connections_do_not_hold_the_slots(raw: Any) -> None:
    """Connections that never send CONNECT take no client place, and are closed after
    ``connect_timeout``: two of them held a 2-client hub "full" for good."""
    from robocli import Hub

    with HubServer(port=0, max_clients=2, connect_timeout=2.0) as srv:
        idle = [socket.create_connection(("127.0.0.1", srv.port), timeout=30) for _ in range(2)]
        idle[1].sendall(_header(0x01, 1, 2, 2)[:10])  # half a CONNECT header, then nothing
        try:
            with (
                Hub.connect("127.0.0.1", srv.port) as one,
                Hub.connect("127.0.0.1", srv.port) as two,
            ):  # both places are free for clients
                one.subscribe("adc", 100)
                two.subscribe("adc")  # silent: joins
            for sock in idle:
                assert sock.recv(64) == b""  # closed by the hub
        finally:
            for sock in idle:
                sock.close()


def test_an_oversize_body_before_connect_closes_the_connection(raw: Any) -> None:
    """A first request announcing more than the hub accepts (64 KiB) is no ros4mat client:
    closed at once (not after the CONNECT timeout); a connected client's is skipped
    (above)."""
    with HubServer(port=0, sim=True, connect_timeout=120.0) as srv:
        good, bad = raw(srv.port), raw(srv.port, timeout=60)
        try:
            good.connect()
            assert good.subscribe("adc", ADC_FAST, buffer=5000).error == 0
            bad.send(_header(0x01, 1, 0xFFFFFFFF, 0xFFFFFFFF))
            assert bad.sock.recv(64) == b""  # before the CONNECT timeout, 120 s
            assert good.pull("adc").error == 0
        finally:
            good.close()
            bad.close()


def test_token_guards_settings_and_serial(raw: Any, wait: Any) -> None:
    with HubServer(port=0, token="s3cret") as srv:
        anon, owner = raw(srv.port), raw(srv.port)
        anon.connect()
        err = anon.subscribe("adc", ADC_FAST)
        assert err.msg_type == r4m.MsgType.SUBSCRIBE_ACK and "unauthorized" in err.error_text
        anon.send(r4m.encode_request(r4m.MsgType.DOUT_CTRL, {"d0": 1, "d1": 1, "d2": 1, "d3": 1}))
        assert "unauthorized" in anon.recv().error_text
        wrong = raw(srv.port)
        wrong.connect(token=b"guess")
        assert "unauthorized" in wrong.subscribe("adc", ADC_FAST).error_text
        owner.connect(token=b"s3cret")
        assert owner.subscribe("adc", ADC_FAST).error == 0
        owner.send(r4m.encode_request(r4m.MsgType.DOUT_CTRL, {"d0": 1, "d1": 0, "d2": 0, "d3": 1}))
        assert anon.subscribe("adc", silent=True).error == 0  # joining reads, changes nothing
        assert anon.pull("adc").error == 0
        # DOUT_CTRL has no reply: wait for the owner's connection to have handled it
        wait(lambda: srv.sensors["adc"]["digital_out"] == [1, 0, 0, 1], what="DOUT_CTRL")
        for c in (anon, owner, wrong):
            c.close()


def _rss() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def test_clients_that_never_pull_stay_bounded(raw: Any, wait: Any) -> None:
    """20 clients subscribed to a 2 kHz ADC and a camera, never pulling: the hub holds one
    ring per sensor (bounded) and O(1) per client, not clients x buffers."""
    with HubServer(port=0, ring_budget=4 << 20) as srv:
        cam = {"fps": 60, "width": 160, "height": 120, "compression": 0, "roi": [0] * 4,
               "id": 0, "exposure": 0, "use_roi": 0}  # fmt: skip
        clients = [raw(srv.port) for _ in range(20)]
        for c in clients:
            c.connect()
            assert (
                c.subscribe("adc", {**ADC_FAST, "freq_acquisition": 2000}, buffer=60000).error == 0
            )
            assert c.subscribe("camera", cam, buffer=1000).error == 0
        sensors = srv.sensors
        ring_bytes = sensors["adc"]["ring_bytes"] + sensors["camera"]["ring_bytes"]
        assert sensors["camera"]["ring_bytes"] <= 4 << 20
        tracemalloc.start()
        rss0 = _rss()
        camera_ring = srv.hub.channels["camera"].ring
        # run until every client's buffer overflowed well past the camera ring
        wait(lambda: camera_ring.pushed > 2 * camera_ring.capacity, timeout=20, what="overflow")
        _, py_peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        grown = _rss() - rss0
        infos = srv.clients
        assert all(i.dropped > 0 for i in infos)
        per_client_copy = 20 * camera_ring.capacity * camera_ring.dtype.itemsize
        assert grown < ring_bytes + (8 << 20) < per_client_copy
        assert py_peak < 4 << 20  # Python allocations: batches, not per-client queues
        mb = 1e6
        print(
            f"rings {ring_bytes / mb:.1f} MB, RSS grew {grown / mb:.1f} MB, Python peak "
            f"{py_peak / mb:.2f} MB; a copy per client: {per_client_copy / mb:.0f} MB"
        )
        for c in clients:
            c.close()


def test_client_that_pulls_but_never_reads_is_dropped(raw: Any, wait: Any) -> None:
    with HubServer(port=0, send_timeout=0.3) as srv:
        slow, good = raw(srv.port), raw(srv.port)
        cam = {"fps": 30, "width": 320, "height": 240, "compression": 0, "roi": [0] * 4,
               "id": 0, "exposure": 0, "use_roi": 0}  # fmt: skip
        slow.connect()
        good.connect()
        assert slow.subscribe("camera", cam, buffer=30).error == 0
        assert good.subscribe("camera", silent=True).error == 0
        pull = r4m.encode_request("camera", client_id=slow.client_id)
        slow.sock.settimeout(10)

        def dropped() -> bool:
            try:
                slow.send(pull)  # asks, never reads the replies
            except OSError:
                return True
            return not [c for c in srv.clients if c.id == slow.client_id and c.connected]

        wait(dropped, timeout=20, what="the slow client to be dropped")
        assert srv.link_stats.tx_dropped > 0  # its unread replies were discarded
        got = wait(lambda: (m := good.pull("camera")).size and m, what="frames")
        assert got.body["infos"][0]["width"] == 320
        slow.close()
        good.close()


def test_random_request_bodies_get_typed_replies(hub: HubServer, client_factory: Any) -> None:
    """Every command id with random bodies: an error reply or none, never a dropped link."""
    c = client_factory(connected=True)
    rng = random.Random(4)
    kinds = [0x03, 0x04, 0x05, 0x06, 0x01, 0x20, 0x24, 0x29]
    for _ in range(300):
        kind = rng.choice(kinds)
        body = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 60)))
        if kind == 0x03 and rng.random() < 0.5:  # a plausible SUBSCRIBE head, random params
            sensor = rng.choice([0x20, 0x21, 0x23, 0x24, 0x26, 0x27, 0x29, 0x2A, 0x22, 0x7F])
            body = bytes([sensor, 0]) + struct.pack("<II", 1, len(body)) + body
        c.send(_header(kind, 1, len(body), len(body)) + body)
        c.send(r4m.encode_request("gps", client_id=c.client_id))  # a marker after each
        while True:
            reply = c.recv()
            if reply.msg_type == r4m.MsgType.GPS:
                break
            assert reply.error == 0 or reply.error_text, reply
        if kind == 0x01:
            c.client_id = reply.client_id
    assert hub.link_stats.session_errors == 0
    assert c.connect() >= 1


def test_a_full_hub_refuses_in_ros4mat(raw: Any) -> None:
    """One client too many gets a ros4mat error reply (CONNECT_ACK with error text), which
    a ros4mat client can parse, not a plain text line; the client inside is served."""
    with HubServer(port=0, max_clients=1) as srv:
        inside, extra = raw(srv.port), raw(srv.port)
        inside.connect()
        reply = extra.request(r4m.MsgType.CONNECT, bytes([r4m.PROTOCOL_VERSION, 0]))
        assert reply.msg_type == r4m.MsgType.CONNECT_ACK and reply.error
        assert "hub full" in reply.error_text
        assert inside.subscribe("adc", ADC_FAST).error == 0
        extra.close()
        inside.close()
