"""Each source's shape, rate and values, over the wire (ros4mat) and directly."""

from __future__ import annotations

import math
import os
import shutil
import signal
import socket
import subprocess
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from robocli.hub_server import HubServer
from robocli.hub_server.sources import AdcSource, BatterySource, GpsSource, ImuSource, SysinfoSource
from robocli.hub_server.sources.imaging import DepthSource, robot_pose
from robocli.protocols import ros4mat as r4m
from robocli.sim.world import World
from tests import paths

DATA = paths.DATA / "ros4mat"


def _pull_until(c: Any, sensor: str, n: int, wait: Any) -> r4m.DecodedPacket:
    got: list[r4m.DecodedPacket] = []

    def enough() -> bool:
        msg = c.pull(sensor)
        if msg.size:
            got.append(msg)
        return sum(m.size for m in got) >= n

    wait(enough, what=f"{n} {sensor} samples")
    return got[-1] if len(got) == 1 else _merge(got)


def _merge(msgs: list[r4m.DecodedPacket]) -> r4m.DecodedPacket:
    body = msgs[0].body
    if isinstance(body, list):
        return r4m.DecodedPacket(msgs[0].msg_type, size=sum(m.size for m in msgs),
                           body=[r for m in msgs for r in m.body])  # fmt: skip
    return msgs[-1]


def _times(records: list[dict[str, Any]]) -> np.ndarray:
    return np.array([r["t"] for r in records])


RECORD_SENSORS = [
    ("adc", {"freq_acquisition": 400, "freq_send": 40, "channels": 255}, 400, 40),
    ("imu", {"freq_acquisition": 250, "freq_send": 50}, 250, 44),
    ("gps", {"freq_acquisition": 20, "freq_send": 20}, 20, 33),
    ("battery", {"freq_acquisition": 50, "freq_send": 50}, 50, 54),
    ("ordinateur", {"freq_acquisition": 20}, 20, 65),
]


@pytest.mark.parametrize("sensor,params,rate,size", RECORD_SENSORS, ids=lambda v: str(v)[:10])
def test_record_sensor_shape_and_rate(
    client_factory: Any, wait: Any, sensor: str, params: dict[str, Any], rate: int, size: int
) -> None:
    c = client_factory(connected=True)
    assert c.subscribe(sensor, params, buffer=1000).error == 0
    msg = _pull_until(c, sensor, 6, wait)
    assert r4m.STRUCT_SIZES[f"msg{sensor.title()}" if sensor != "ordinateur" else "msgComputer"]
    assert r4m.record_dtype(sensor).itemsize == size
    t = _times(msg.body)
    assert np.allclose(np.diff(t), 1 / rate, rtol=1e-3)


def test_camera_raw_frames(client_factory: Any, wait: Any) -> None:
    c = client_factory(connected=True)
    params = {"fps": 30, "width": 160, "height": 120, "id": 0, "compression": 0, "exposure": 300,
              "use_roi": 0, "roi": [0, 0, 0, 0]}  # fmt: skip
    assert c.subscribe("camera", params, buffer=10).error == 0
    msg = _pull_until(c, "camera", 2, wait)
    infos, images = msg.body["infos"], msg.body["images"]
    assert len(infos) == len(images) == msg.size >= 2
    for info, img in zip(infos, images, strict=True):
        assert (info["width"], info["height"], info["channels"]) == (160, 120, 3)
        assert info["compression"] == 0 and info["size_data"] == len(img) == 160 * 120 * 3
    a = np.frombuffer(images[0], np.uint8).reshape(120, 160, 3)
    b = np.frombuffer(images[-1], np.uint8).reshape(120, 160, 3)
    assert (a != b).any()  # the scene moves
    assert np.allclose(np.diff([i["t"] for i in infos]), 1 / 30, rtol=1e-3)


def test_camera_jpeg_request_without_an_encoder_is_raw_and_flagged(
    hub: HubServer, client_factory: Any, wait: Any
) -> None:
    c = client_factory(connected=True)
    params = {"fps": 10, "width": 160, "height": 120, "id": 0, "compression": 80,
              "exposure": 300, "use_roi": 0, "roi": [0, 0, 0, 0]}  # fmt: skip
    assert c.subscribe("camera", params).error == 0
    info = _pull_until(c, "camera", 1, wait).body["infos"][0]
    jpeg = hub.sensors["camera"]["jpeg"]
    if jpeg.startswith("unavailable"):
        assert info["compression"] == 0 and info["size_data"] == 160 * 120 * 3
    else:
        assert info["compression"] == 80 and info["size_data"] < 160 * 120 * 3


def test_stereo_pairs_share_a_timestamp(client_factory: Any, wait: Any) -> None:
    c = client_factory(connected=True)
    params = {"fps": 20, "width": 160, "height": 120, "id_left": 0, "id_right": 1,
              "compression": 0, "exposure_left": 300, "exposure_right": 300, "use_roi": 0,
              "roi_left": [0] * 4, "roi_right": [0] * 4}  # fmt: skip
    assert c.subscribe("camera_stereo", params).error == 0
    msg = _pull_until(c, "camera_stereo", 2, wait)
    infos, images = msg.body["infos"], msg.body["images"]
    assert len(infos) == len(images) == 2 * msg.size
    for k in range(msg.size):
        left, right = infos[2 * k], infos[2 * k + 1]
        assert left["t"] == right["t"] and left["size_data"] == right["size_data"] == 57600
        assert images[2 * k] != images[2 * k + 1]  # disparity


def test_depth_camera_rgb_and_depth(client_factory: Any, wait: Any) -> None:
    c = client_factory(connected=True)
    params = bytes.fromhex("1e00 4001 f000 00 00 00 0000 00 00" + "00" * 8 + "00" + "00" * 8)
    head = {"sensor": 0x29, "silent": 0, "buffer_size": 5, "params_size": 30}
    assert len(params) == 30
    c.send(r4m.encode_packet(r4m.MsgType.SUBSCRIBE, r4m.Subscribe.build(head) + params))
    assert c.recv().error == 0
    msg = _pull_until(c, "kinect", 1, wait)
    info, image = msg.body["infos"][0], msg.body["images"][0]
    assert info["rgb"]["t"] == info["depth"]["t"]
    assert (info["rgb"]["width"], info["rgb"]["height"]) == (320, 240)
    assert len(image["rgb"]) == 320 * 240 * 3 and len(image["depth"]) == 320 * 240 * 2
    depth = np.frombuffer(image["depth"], "<u2").reshape(240, 320)
    src = DepthSource()
    src.configure({"width_rgb": 320, "height_rgb": 240})
    assert np.array_equal(depth, src.depth_image(info["depth"]["t"]))
    assert 100 < depth[0].min() and depth[0].max() < 8000  # walls in the default room


def test_laser_scans_the_pioneer_world(client_factory: Any, wait: Any) -> None:
    c = client_factory(connected=True)
    assert c.subscribe("hokuyo", {"freq_acquisition": 40}, buffer=40).error == 0
    msg = _pull_until(c, "hokuyo", 3, wait)
    info = msg.body["infos"][-1]
    ranges = np.array(msg.body["ranges"][-1])
    assert info["size_data"] == 1081 * 4 and ranges.shape == (1081,)
    assert math.degrees(info["angle_max"] - info["angle_min"]) == pytest.approx(270, abs=1e-3)
    x, y, th = robot_pose(info["t"])
    truth = World.default().cast(np.full(1081, x), np.full(1081, y),
                                 th + np.linspace(info["angle_min"], info["angle_max"], 1081),
                                 30.0)  # fmt: skip
    assert np.median(np.abs(ranges - truth)) < 0.03  # noise 1 cm
    times = [i["t"] for i in msg.body["infos"]]
    assert np.allclose(np.diff(times), 1 / 40, rtol=1e-3)


# ------------------------------------------------------------------------ sources directly


def test_adc_polar_map_experiment() -> None:
    src = AdcSource()
    src.configure({"freq_acquisition": 1000, "channels": 0b11})
    t = np.arange(0, 12.0, 1e-3)  # one turn at 30 deg/s
    rec = src.sample(t)
    ch = rec["channels"]
    assert (ch[:, 2:] == 0).all()  # masked out
    rate = (ch[:, 1] - AdcSource.GYRO_ZERO) / AdcSource.GYRO_GAIN
    assert rate.mean() == pytest.approx(30.0, abs=0.1)
    heading = np.cumsum(np.radians(rate)) * 1e-3  # what the students integrate
    assert heading[-1] == pytest.approx(2 * math.pi, rel=0.01)
    d = World.default().cast(np.full(len(t), -3.0), np.full(len(t), 3.8), src.heading(t), 5.0)
    near = d < 0.6
    assert ch[near, 0].mean() > ch[~near, 0].mean() + 0.3  # closer wall, higher voltage


def test_imu_gravity_bias_noise() -> None:
    src = ImuSource()
    rec = src.sample(np.arange(0, 10, 0.01))
    acc = rec["acc"].astype(float)
    assert np.linalg.norm(acc, axis=1).mean() == pytest.approx(1.0, abs=0.03)
    assert 0.002 < acc[:, 0].std() < 0.02  # noise on the axis with no motion
    assert rec["gyro"][:, 1].mean() == pytest.approx(ImuSource.GYRO_BIAS[1], abs=0.1)
    assert np.linalg.norm(rec["mag"], axis=1).mean() == pytest.approx(51.3, abs=1.0)


def test_gps_and_battery_values() -> None:
    gps = GpsSource().sample(np.arange(0.0, 60.0))
    assert (gps["state"] == r4m.GpsState.FIX_3D).all()
    assert abs(gps["latitude"] - 46.7817).max() < 0.001
    assert abs(gps["longitude"] + 71.2747).max() < 0.001
    bat = BatterySource().sample(np.array([0.0, 600.0]))
    assert (bat["n_cells"] == 3).all() and bat["vtotal"][0] == pytest.approx(12.6, abs=0.05)
    assert bat["state_of_charge"][1] == pytest.approx(0.9)


@pytest.mark.skipif(not Path("/proc/meminfo").exists(), reason="Linux /proc only")
def test_sysinfo_on_this_machine() -> None:
    src = SysinfoSource()
    src.start(0.0)
    time.sleep(0.05)  # a few 10 ms clock ticks between the two readings of /proc/stat
    rec = src.sample(np.array([1.0]))[0]
    total = int(Path("/proc/meminfo").read_text().split()[1])
    used, free, _buffers = (int(v) for v in rec["memory"])
    assert used + free == total
    assert rec["state"] == r4m.ComputerState.OK
    assert sum(rec["cpu_load"]) == pytest.approx(100.0, abs=0.5)
    assert rec["unix_load"].tolist() == pytest.approx(os.getloadavg(), abs=0.5)
    again = src.sample(np.array([1.0]))[0]  # at once: no tick yet, the last split again
    assert sum(again["cpu_load"]) == pytest.approx(100.0, abs=0.5)


# ------------------------------------------------------------------------ gpsd


@pytest.fixture
def gpsd_replay() -> Iterator[tuple[int, threading.Event]]:
    """A fake gpsd on loopback: after ?WATCH, replays the recorded JSON stream."""
    lines = (DATA / "gpsd_session.jsonl").read_bytes()
    listener = socket.create_server(("127.0.0.1", 0))
    watched = threading.Event()

    def serve() -> None:
        try:
            conn, _ = listener.accept()
        except OSError:
            return
        with conn:
            conn.settimeout(10)
            if conn.recv(1024).startswith(b"?WATCH="):
                watched.set()
                conn.sendall(lines)
                conn.recv(1)  # until the hub closes

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    yield listener.getsockname()[1], watched
    listener.close()
    thread.join(5)


def test_gpsd_source_against_a_recorded_stream(
    gpsd_replay: tuple[int, threading.Event], raw: Any, wait: Any
) -> None:
    port, watched = gpsd_replay
    with HubServer(port=0, sim=False, gpsd=f"127.0.0.1:{port}") as srv:
        assert set(srv.sensors) == {"gps", "sysinfo"} and not srv.sensors["gps"]["simulated"]
        c = raw(srv.port)
        c.connect()
        assert c.subscribe("gps", {"freq_acquisition": 1, "freq_send": 1}, buffer=10).error == 0
        msg = _pull_until(c, "gps", 4, wait)
        assert watched.is_set()
        fixes = msg.body
        assert [f["state"] for f in fixes] == [0x00, 0x10, 0x20, 0x20]
        assert math.isnan(fixes[0]["latitude"])
        assert fixes[2]["latitude"] == pytest.approx(46.781740)
        assert fixes[2]["longitude"] == pytest.approx(-71.274690)
        assert fixes[2]["altitude"] == pytest.approx(89.9, abs=1e-4)  # altMSL
        assert fixes[3]["climb"] == pytest.approx(0.4)
        assert srv.hub.channels["gps"].source.bad_lines == 1
        c.close()


def test_real_camera_only_with_opencv(raw: Any) -> None:
    from robocli.hub_server.sources.opencv import opencv_available

    with HubServer(port=0, sim=False) as srv:
        if not opencv_available():
            assert "camera" not in srv.sensors  # robocli-robots[camera] not installed
            return
        assert not srv.sensors["camera"]["simulated"]
        c = raw(srv.port)
        c.connect()
        params = {"fps": 10, "width": 320, "height": 240, "id": 99, "compression": 0,
                  "exposure": 0, "use_roi": 0, "roi": [0] * 4}  # fmt: skip
        err = c.subscribe("camera", params)
        assert err.error and "video99" in err.error_text
        c.close()


@pytest.mark.skipif(shutil.which("gpsfake") is None, reason="gpsd's gpsfake is not installed")
def test_gpsd_source_against_gpsfake(raw: Any, wait: Any) -> None:
    """A real gpsd fed by gpsd's own gpsfake with an NMEA log (CI installs gpsd-clients)."""
    with socket.socket() as probe:  # a free port for gpsfake's gpsd
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    log = str(DATA / "gpsfake.nmea")
    proc = subprocess.Popen(
        ["gpsfake", "-q", "-c", "0.1", "-P", str(port), log],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
    )  # fmt: skip
    try:
        with HubServer(port=0, sim=False, gpsd=f"127.0.0.1:{port}") as srv:
            c = raw(srv.port)
            c.connect()
            assert (
                c.subscribe("gps", {"freq_acquisition": 1, "freq_send": 1}, buffer=100).error == 0
            )
            fixes: list[dict[str, Any]] = []

            def located() -> bool:
                fixes.extend(f for f in c.pull("gps").body or [] if f["state"] >= 0x10)
                return bool(fixes)

            wait(located, timeout=30, what="a fix from gpsd")
            assert fixes[0]["latitude"] == pytest.approx(46.7817, abs=1e-3)
            assert fixes[0]["longitude"] == pytest.approx(-71.2747, abs=1e-3)
            c.close()
    finally:
        os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(10)
