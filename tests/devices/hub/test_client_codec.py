"""Hub client without a hub: its requests against the original client's bytes (golden
vectors) and its zero-copy decoding of every sensor reply against declared records."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from robocli.devices.hub.client import ClockSync, parse_hub, resolution, subscribe_body
from robocli.devices.hub.decode import decode_jpeg, decode_reading
from robocli.errors import DeviceError, InvalidArgument, ProtocolError
from robocli.protocols import ros4mat as r4m
from tests import reference

SPEC = {v["name"]: bytes.fromhex(v["hex"]) for v in reference.load_spec("ros4mat")["vectors"]}

# (vector, sensor, rate, keyword arguments), as ros4mat('subscribe', ...) was called
SUBSCRIBES = [
    ("subscribe_adc", "adc", 100, {"buffer": 100, "channels": 255}),
    ("subscribe_imu", "imu", 50, {}),
    ("subscribe_gps", "gps", 1, {}),
    ("subscribe_ordinateur", "ordinateur", 2, {}),
    ("subscribe_hokuyo", "hokuyo", 10, {"buffer": 30}),
    ("subscribe_camera", "camera", 15, {"resolution": "640x480"}),
    ("subscribe_kinect", "kinect", 30, {"resolution": "640x480"}),
    ("subscribe_camera_stereo", "camera_stereo", 15, {"resolution": "320x240"}),
]


@pytest.mark.parametrize("case", SUBSCRIBES, ids=lambda c: c[0])
def test_subscribe_bytes_are_the_original_clients(case: tuple[str, str, int, Any]) -> None:
    vector, sensor, rate, kwargs = case
    body = subscribe_body(sensor, rate, **kwargs)
    assert r4m.encode_request(r4m.MsgType.SUBSCRIBE, body, client_id=7) == SPEC[vector]


def test_silent_subscribe_and_other_requests() -> None:
    body = subscribe_body("adc")
    assert (
        r4m.encode_request(r4m.MsgType.SUBSCRIBE, body, client_id=7) == SPEC["subscribe_adc_silent"]
    )
    with pytest.raises(InvalidArgument, match="silent"):
        subscribe_body("adc", buffer=5)


def test_subscribe_rules() -> None:
    # an explicit poll rate is clamped to the capture rate; the default is not
    assert subscribe_body("imu", 20, poll=500)["params"]["freq_send"] == 20
    assert subscribe_body("gps", 1)["params"]["freq_send"] == 10
    assert resolution("645x480") == (640, 480)
    assert resolution("50x50") == (160, 120) and resolution("9999") == (1600, 1200)
    with pytest.raises(InvalidArgument, match="rate"):
        subscribe_body("adc", 0)
    with pytest.raises(InvalidArgument, match="rate"):
        subscribe_body("adc", float("nan"))
    with pytest.raises(InvalidArgument, match="channels"):
        subscribe_body("adc", 10, channels=0x100)
    with pytest.raises(InvalidArgument, match="fps_depth"):
        subscribe_body("imu", 10, fps_depth=3)
    with pytest.raises(InvalidArgument, match="unknown sensor 'lidar'"):
        subscribe_body("lidar", 10)


def test_parse_hub() -> None:
    assert parse_hub("10.0.0.2") == ("10.0.0.2", 1500)
    assert parse_hub("tcp://h:1600") == ("h", 1600)
    assert parse_hub(":7") == ("127.0.0.1", 7)
    with pytest.raises(InvalidArgument, match="port"):
        parse_hub("h:x")


def _reply(kind: int, body: bytes, n: int, *, compress: bool = False, ts: float = 5.0) -> bytes:
    return r4m.encode_packet(kind, body, size=n, compress=compress, packet_timestamp=ts)


def _cam(w: int, h: int, c: int, size: int, t: float, compression: int = 0) -> bytes:
    info = {"width": w, "height": h, "channels": c, "size_data": size,
            "compression": compression, "t": t}  # fmt: skip
    data: bytes = r4m.Cam.build(info)
    return data


@pytest.mark.parametrize("compress", [False, True])
def test_fixed_records_shapes_and_values(compress: bool) -> None:
    rng = np.random.default_rng(1)
    n = 5
    adc = [{"channels": list(rng.random(8)), "t": 1.0 + i / 100} for i in range(n)]
    reading = decode_reading(r4m.encode_records("adc", adc, compress=compress), "adc")
    data, t = reading
    assert data.shape == (8, n) and t.shape == (n,)
    np.testing.assert_allclose(data[:, 2], np.float32(adc[2]["channels"]))
    np.testing.assert_allclose(t, [r["t"] for r in adc])
    imu = [{"acc": [i, 2, 3], "gyro": [4, 5, 6], "mag": [7, 8, i], "t": float(i)} for i in range(n)]
    reading = decode_reading(r4m.encode_records("imu", imu, compress=compress), "imu")
    assert reading.data.shape == (9, n) and reading.accel.shape == (3, n)
    assert reading.accel[0].tolist() == list(range(n)) and reading.mag[2, 4] == 4
    gps = [{"state": 0x20, "latitude": 46.5, "longitude": -71.25, "altitude": 80.0,
            "speed": 1.0, "track": 90.0, "climb": 0.5, "t": 3.0}]  # fmt: skip
    reading = decode_reading(r4m.encode_records("gps", gps, compress=compress), "gps")
    assert reading.data[:, 0].tolist() == [32, -71.25, 46.5, 80.0, 1.0, 90.0, 0.5]  # lon first
    assert reading.longitude[0] == -71.25
    comp = [{"state": 0, "cpu_temperature": 50.0, "unix_load": [1, 2, 3], "t": 4.0,
             "cpu_load": [10, 20, 0, 70, 0, 0, 0], "memory": [100, 200, 300]}]  # fmt: skip
    reading = decode_reading(r4m.encode_records("computer", comp, compress=compress), "computer")
    assert reading.data.shape == (15, 1)
    assert reading.data[:, 0].tolist() == [0, 50, 1, 2, 3, 10, 20, 0, 70, 0, 0, 0, 100, 200, 300]
    bat = [{"vtotal": 12.5, "current": 1.5, "n_cells": 3, "vcell": [4.1, 4.2, 4.2, 0, 0, 0, 0, 0],
            "state": 1, "state_of_charge": 0.5, "t": 2.0}]  # fmt: skip
    reading = decode_reading(r4m.encode_records("battery", bat, compress=compress), "battery")
    assert reading.data.shape == (13, 1) and reading.vtotal[0] == 12.5
    assert reading.vcell.shape == (8, 1)


def test_views_share_the_received_bytes() -> None:
    frame = r4m.encode_records("adc", [{"channels": [0.5] * 8, "t": 1.0}] * 3)
    reading = decode_reading(frame, "adc")
    assert np.shares_memory(reading.data, np.frombuffer(frame, np.uint8))
    assert not reading.data.flags.writeable


def test_empty_pull_and_clock() -> None:
    reading = decode_reading(_reply(r4m.MsgType.ADC, b"", 0), "adc", offset=2.0)
    assert reading.data.shape == (8, 0) and len(reading) == 0
    frame = r4m.encode_records("imu", [{"acc": [0] * 3, "gyro": [0] * 3, "mag": [0] * 3,
                                        "t": 10.0}])  # fmt: skip
    reading = decode_reading(frame, "imu", offset=2.5)
    assert reading.t[0] == 7.5 and reading.hub_t[0] == 10.0


def test_camera_stereo_kinect_laser() -> None:
    w, h, n = 8, 6, 3
    imgs = [np.full((h, w, 3), i, np.uint8) for i in range(n)]
    body = b"".join(_cam(w, h, 3, w * h * 3, float(i)) for i in range(n))
    body += b"".join(img.tobytes() for img in imgs)
    reading = decode_reading(_reply(r4m.MsgType.WEBCAM, body, n), "camera")
    assert reading.data.shape == (h, w, 3, n) and reading.data[..., 2].max() == 2
    stereo = b"".join(_cam(w, h, 3, w * h * 3, float(i // 2)) for i in range(2 * n))
    stereo += b"".join(np.full((h, w, 3), i, np.uint8).tobytes() for i in range(2 * n))
    reading = decode_reading(_reply(r4m.MsgType.WEBCAM_STEREO, stereo, n), "camera_stereo")
    assert reading.left.shape == reading.right.shape == (h, w, 3, n)
    assert reading.left[0, 0, 0].tolist() == [0, 2, 4] and reading.right[0, 0, 0, 1] == 3
    assert reading.t.tolist() == [0.0, 1.0, 2.0]
    infos = b"".join(_cam(w, h, 3, w * h * 3, float(i)) + _cam(w, h, 1, w * h * 2, float(i))
                     for i in range(n))  # fmt: skip
    blobs = b"".join(
        np.full((h, w, 3), i, np.uint8).tobytes() + np.full((h, w), 1000 + i, "<u2").tobytes()
        for i in range(n)
    )
    reading = decode_reading(_reply(r4m.MsgType.KINECT, infos + blobs, n), "kinect")
    assert reading.rgb.shape == (h, w, 3, n) and reading.depth.shape == (h, w, n)
    assert reading.depth[0, 0].tolist() == [1000, 1001, 1002]
    beams = 11
    scans = [np.linspace(0.1, 5, beams, dtype="<f4") * (i + 1) for i in range(n)]
    infos = b"".join(
        r4m.Hokuyo.build({"angle_min": -2.0, "angle_max": 2.0, "angle_increment": 0.4,
                          "time_increment": 1e-4, "range_min": 0.02, "range_max": 30.0 + i,
                          "t": float(i), "size_data": beams * 4})
        for i in range(n)
    )  # fmt: skip
    frame = _reply(r4m.MsgType.HOKUYO, infos + b"".join(s.tobytes() for s in scans), n)
    reading = decode_reading(frame, "hokuyo")
    ranges, t = reading
    assert ranges.shape == (beams, n)
    np.testing.assert_allclose(ranges[:, 1], scans[1])
    np.testing.assert_allclose(reading.info, [-2.0, 2.0, 0.4, 0.02, 32.0, 1e-4], rtol=1e-6)


def test_bad_replies_raise_typed_errors() -> None:
    with pytest.raises(DeviceError, match="not subscribed"):
        decode_reading(r4m.encode_error(r4m.MsgType.ADC, "not subscribed"), "adc")
    short = _reply(r4m.MsgType.ADC, b"\0" * 39, 1)
    with pytest.raises(ProtocolError, match="39 body bytes"):
        decode_reading(short, "adc")
    body = _cam(8, 6, 3, 999, 0.0) + b"\0" * 999
    with pytest.raises(ProtocolError, match="raw 8x6"):
        decode_reading(_reply(r4m.MsgType.WEBCAM, body, 1), "camera")
    bomb = bytearray(_reply(r4m.MsgType.ADC, b"\0" * 400, 10, compress=True))
    bomb[10:14] = (40).to_bytes(4, "little")  # declares less than it inflates to
    with pytest.raises(ProtocolError, match="inflates past"):
        decode_reading(bytes(bomb), "adc")


def test_clock_sync_min_rtt() -> None:
    sync = ClockSync(window=4)
    sync.add(0.0, 0.010, 100.009)  # asymmetric slow exchange: error 4 ms
    sync.add(1.0, 1.0002, 101.0001)  # fast: exact
    sync.add(2.0, 2.005, 102.0)
    assert sync.offset == pytest.approx(100.0) and sync.rtt == pytest.approx(0.0002)
    sync.add(3.0, 3.0, 0.0)  # packet without a send time: ignored
    assert sync.rtt == pytest.approx(0.0002)
    for broken in (float("inf"), float("nan")):  # a broken send time is no sample either
        sync.add(4.0, 4.0, broken)
        assert sync.offset == pytest.approx(100.0) and sync.rtt == pytest.approx(0.0002)


def test_decoding_a_camera_reply_copies_no_image() -> None:
    import tracemalloc

    w, h, n = 320, 240, 8
    body = b"".join(_cam(w, h, 3, w * h * 3, float(i)) for i in range(n)) + bytes(w * h * 3 * n)
    frame = _reply(r4m.MsgType.WEBCAM, body, n)
    tracemalloc.start()
    try:
        reading = decode_reading(frame, "camera", offset=0.5)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert reading.data.shape == (h, w, 3, n)
    assert peak < 64 * 1024 < len(frame) // 20  # 1.8 MB of frames, views only


def _scripted_hub(stamp: float) -> tuple[Any, Any]:
    """A Hub on a socketpair whose other end plays the hub: its CONNECT_ACK carries
    ``stamp`` (robocli's hub stamps it; the original server sends 0)."""
    import socket

    from robocli.devices.hub.client import Hub
    from robocli.transports import SocketTransport

    a, b = socket.socketpair()
    b.settimeout(10.0)
    b.sendall(r4m.encode_packet(r4m.MsgType.CONNECT_ACK, size=0, client_id=7,
                                packet_timestamp=stamp))  # fmt: skip
    hub = Hub.from_transport(SocketTransport(a, "pair://hub"), timeout=10.0)
    assert b.recv(4096) == SPEC["connect"]
    return hub, b


def test_requests_without_a_reply_to_the_original_server_are_its_bytes() -> None:
    """The original server answers neither DOUT_CTRL nor UNSUBSCRIBE, and stamps no
    CONNECT_ACK: the client sends the original client's bytes and waits for nothing."""
    hub, peer = _scripted_hub(0.0)
    with peer, hub:
        assert not hub.answers_refusals and hub.clock_offset is None
        hub.digital_out(1, 0, 1, 0)
        hub.unsubscribe("adc")
        want = SPEC["digital_out_1010"] + SPEC["unsubscribe_adc"]
        got = b""
        while len(got) < len(want):
            got += peer.recv(4096)
        assert got == want


def test_a_refused_unsubscribe_raises() -> None:
    """To a hub that answers refusals, UNSUBSCRIBE (no reply in ros4mat) is followed by a
    fence, and an error reply before the fence's reply raises DeviceError."""
    hub, peer = _scripted_hub(1000.0)
    with peer, hub:
        assert hub.answers_refusals and hub.clock_offset is not None
        peer.sendall(r4m.encode_error(r4m.MsgType.UNSUBSCRIBE, "not connected", client_id=7)
                     + r4m.encode_error(0x28, "unknown message id 0x28", client_id=7))  # fmt: skip
        with pytest.raises(DeviceError, match="^hub refused UNSUBSCRIBE: not connected"):
            hub.unsubscribe("adc")
        fence = r4m.encode_packet(0x28, client_id=7, size=0)
        sent = b""
        while len(sent) < len(SPEC["unsubscribe_adc"]) + len(fence):
            sent += peer.recv(4096)
        assert sent == SPEC["unsubscribe_adc"] + fence
        peer.sendall(r4m.encode_error(0x28, "unknown message id 0x28", client_id=7))
        hub.unsubscribe("imu")  # a fence reply alone: accepted


def _jpeg(w: int, h: int, level: int = 128) -> bytes:
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.full((h, w, 3), level, np.uint8)).save(buf, format="JPEG", quality=80)
    return buf.getvalue()


def test_undecodable_replies_are_protocol_errors() -> None:
    """Every way a reply can be wrong is a ProtocolError, never a bare ValueError (found by
    the decode-hub-reply fuzz target)."""
    with pytest.raises(ProtocolError, match="0x30 is not a sensor reply"):
        decode_reading(_reply(0x30, b"\0" * 40, 1), "adc")  # no such message id
    with pytest.raises(ProtocolError, match="shorter than its header"):
        decode_reading(b"\x20\x00", "adc")
    small, large = _jpeg(8, 6), _jpeg(16, 12)
    body = _cam(8, 6, 3, len(small), 0.0, 80) + _cam(16, 12, 3, len(large), 0.1, 80)
    with pytest.raises(ProtocolError, match="JPEG frames of different sizes"):
        decode_reading(_reply(r4m.MsgType.WEBCAM, body + small + large, 2), "camera")
    huge = bytearray(small)  # a few hundred bytes declaring 60000 x 60000 pixels
    sof = huge.index(b"\xff\xc0")
    huge[sof + 5 : sof + 9] = (60000).to_bytes(2, "big") * 2
    body = _cam(60000, 60000, 3, len(huge), 0.0, 80) + bytes(huge)
    with pytest.raises(ProtocolError, match="DecompressionBomb"):  # Pillow's own limit
        decode_reading(_reply(r4m.MsgType.WEBCAM, body, 1), "camera")
    huge[sof + 5 : sof + 9] = (600).to_bytes(2, "big") * 2  # under it, over a reply's budget
    with pytest.raises(ProtocolError, match=r"600x600 exceeds the 1 MiB"):
        decode_jpeg(bytes(huge), max_bytes=1 << 20)
    body = _cam(8, 6, 3, 20, 0.0, 80) + b"not a JPEG at all...."[:20]
    with pytest.raises(ProtocolError, match="undecodable JPEG"):
        decode_reading(_reply(r4m.MsgType.WEBCAM, body, 1), "camera")
    w, h = 0xFFFF0000, 0xFFFF0000  # zero bytes: w x h x 0 channels
    with pytest.raises(ProtocolError, match="image"):
        decode_reading(_reply(r4m.MsgType.WEBCAM, _cam(w, h, 0, 0, 0.0), 1), "camera")


def test_kinect_jpeg_frames_of_their_own_sizes() -> None:
    """A JPEG RGB frame has the size its content compresses to: a Kinect reply's frames
    differ in size and decode each from its own bytes (the depth blob after each)."""
    w, h = 8, 6
    blobs, infos = b"", b""
    for i, level in enumerate((0, 255, 77)):
        rgb = _jpeg(w, h, level) + b"\0" * i  # a different size each (JPEG ignores the tail)
        depth = np.full((h, w), 1000 + i, "<u2").tobytes()
        infos += _cam(w, h, 3, len(rgb), float(i), 80) + _cam(w, h, 1, len(depth), float(i))
        blobs += rgb + depth
    reading = decode_reading(_reply(r4m.MsgType.KINECT, infos + blobs, 3), "kinect")
    assert reading.rgb.shape == (h, w, 3, 3) and reading.depth.shape == (h, w, 3)
    assert np.abs(reading.rgb[..., 1].astype(int) - 255).max() <= 3
    assert reading.depth[0, 0].tolist() == [1000, 1001, 1002]


def test_a_hub_sending_infinite_times_is_read() -> None:
    """Sample times from a hub may be anything: an infinite one is not a lost-sample count
    of infinity (it raised OverflowError)."""
    hub, peer = _scripted_hub(1000.0)
    with peer, hub:
        peer.sendall(r4m.encode_packet(r4m.MsgType.SUBSCRIBE_ACK, size=0, client_id=7))
        hub.subscribe("adc", 1000)
        times = [5.0, 5.001, 5.002, float("inf"), 5.004]
        adc = [{"channels": [0.0] * 8, "t": t} for t in times]
        peer.sendall(r4m.encode_records("adc", adc, packet_timestamp=5.01))
        reading = hub.read("adc")
        assert reading.hub_t.tolist() == times and reading.lost == 0
