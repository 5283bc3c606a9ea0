"""Data replies written as gathered buffers (header + records, no join): in order with the
other replies of the same batch of requests, and whole when the client's socket is full and
the rest waits in the link's backlog."""

from __future__ import annotations

import socket
from typing import Any

import numpy as np

from robocli.hub_server import HubServer
from robocli.protocols import ros4mat as r4m

CAM = {"fps": 30, "width": 320, "height": 240, "compression": 0, "roi": [0] * 4, "id": 0,
       "exposure": 0, "use_roi": 0}  # fmt: skip
IMU = {"freq_acquisition": 200, "freq_send": 50}


def _frames(msg: r4m.DecodedPacket) -> tuple[list[float], list[bytes]]:
    body = msg.body or {"infos": [], "images": []}
    return [i["t"] for i in body["infos"]], [bytes(im) for im in body["images"]]


def test_pipelined_requests_get_their_replies_in_order(
    hub: HubServer, client_factory: Any, wait: Any
) -> None:
    c = client_factory(connected=True)
    assert c.subscribe("camera", CAM, buffer=30).error == 0
    ring = hub.hub.channels["camera"].ring
    wait(lambda: ring.pushed >= 2, what="camera frames")
    sub_imu = {"sensor": "imu", "silent": 0, "buffer_size": 100, "params": IMU}
    batch = [
        r4m.encode_request("camera", client_id=c.client_id),
        r4m.encode_request(r4m.MsgType.SUBSCRIBE, sub_imu, client_id=c.client_id),
        r4m.encode_request("imu", client_id=c.client_id),
        r4m.encode_request("camera", client_id=c.client_id),
        r4m.encode_request(r4m.MsgType.SUBSCRIBE, sub_imu, client_id=c.client_id),
    ]
    c.send(b"".join(batch))  # one write: the hub frames them from one recv
    kinds = [c.recv().msg_type for _ in batch]
    assert kinds == [r4m.MsgType.WEBCAM, r4m.MsgType.SUBSCRIBE_ACK, r4m.MsgType.IMU,
                     r4m.MsgType.WEBCAM, r4m.MsgType.SUBSCRIBE_ACK]  # fmt: skip


def test_replies_larger_than_the_socket_buffers_arrive_whole(raw: Any, wait: Any) -> None:
    """A client with a tiny receive buffer pipelines pulls of a 320x240 camera without
    reading: most of each reply waits in the hub's backlog. Read at last, every frame is
    there once, whole (each image equals the one another client pulled) and in order."""
    with HubServer(port=0, sim=True) as srv:
        slow = raw(srv.port)
        slow.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 32768)
        ref = raw(srv.port)
        slow.connect()
        ref.connect()
        assert slow.subscribe("camera", CAM, buffer=100).error == 0
        assert ref.subscribe("camera", silent=True, buffer=100).error == 0
        ring = srv.hub.channels["camera"].ring
        wait(lambda: ring.pushed >= 1, what="a camera frame")
        ref.pull("camera")  # from here on, ref sees every frame slow sees
        slow.pull("camera")
        # 20 frames (4.6 MB, more than a socket's largest send buffer) in the first reply,
        # then more pulls while it still waits in the backlog
        pulls, base = 4, ring.pushed
        for k in range(pulls):
            wait(lambda k=k: ring.pushed >= base + 20 + k, what="camera frames")
            slow.send(r4m.encode_request("camera", client_id=slow.client_id))
        got_t: list[float] = []
        got_img: list[bytes] = []
        for _ in range(pulls):
            msg = slow.recv()
            assert msg.msg_type == r4m.MsgType.WEBCAM and msg.error == 0
            t, img = _frames(msg)
            got_t += t
            got_img += img
        ref_t: list[float] = []
        ref_img: list[bytes] = []
        while len(ref_t) < len(got_t) or ref_t[-1] < got_t[-1]:
            t, img = _frames(ref.pull("camera"))
            ref_t += t
            ref_img += img
        assert len(got_t) >= 20 + pulls - 1 and np.all(np.diff(got_t) > 0)
        index = {t: i for i, t in enumerate(ref_t)}
        assert all(got_img[k] == ref_img[index[t]] for k, t in enumerate(got_t))
        assert all(len(im) == 320 * 240 * 3 for im in got_img)
        slow.close()
        ref.close()
