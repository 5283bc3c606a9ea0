"""Recording each device into MCAP against the built-in simulators over real sockets; every
file is read back with the ``mcap`` package's own reader, and every JSON message is checked
against the schema its channel names."""

from __future__ import annotations

import base64
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from robocli.devices.arm import Arm
from robocli.devices.hub.client import Hub
from robocli.devices.pioneer import Pioneer
from robocli.hub_server import HubServer
from robocli.io.capture import CaptureStats, read_capture
from robocli.io.record import RAW_SCHEMA, Recorder, info
from robocli.kinematics import load_model
from robocli.kinematics.fk import fk
from robocli.protocols import arcos
from tests.io.readback import by_topic, decoded, messages
from tests.paths import DATA
from tests.waiting import wait_for

FOXGLOVE_PIONEER = {
    "/pioneer/pose": "foxglove.PoseInFrame",
    "/pioneer/tf": "foxglove.FrameTransform",
    "/pioneer/sonar": "foxglove.LaserScan",
    "/pioneer/laser": "foxglove.LaserScan",
    "/pioneer/state": "robocli.pioneer.State",
}


Seen = list[tuple[str, bytes]]


def _record_pioneer(url: str, path: Path, sips: int = 12,
                    **options: Any) -> tuple[Seen, list[Any], int, int]:  # fmt: skip
    """Drive a simulated Pioneer while recording it from the handshake on; returns what a
    live dump's listener saw (direction, whole frame), the poses the client decoded, and
    the wall clock (epoch ns) around the session."""
    seen: list[tuple[str, bytes]] = []
    poses = []
    before = time.time_ns()
    with Recorder(path, **options) as rec:
        listener = rec.listener("pioneer", "arcos", url=url)
        with Pioneer.connect(url, listeners=[listener, lambda d, p, t: seen.append(
                (d, arcos.frame(p)))], laser=True) as robot:  # fmt: skip
            assert rec.add(robot, listener.name) == "pioneer"
            robot.enable_motors()
            robot.set_velocity(0.3, 0.4)
            for _ in range(sips):
                poses.append(robot.wait_for_sip().pose)
            robot.sim.wait_for_laser(5.0)
        assert rec.stats.dropped == 0
    return seen, poses, before, time.time_ns()


def test_pioneer_channels_foxglove_opens(pioneer_url: str, tmp_path: Path) -> None:
    path = tmp_path / "pioneer.mcap"
    _, poses, before, after = _record_pioneer(pioneer_url, path)
    topics = by_topic(path)
    for topic, schema in FOXGLOVE_PIONEER.items():
        assert topic in topics, sorted(topics)
        for item in topics[topic]:
            assert item[0].name == schema
            decoded(item)  # JSON that fits its schema
    # every pose the client decoded is in the recording, in the odom frame
    recorded = [decoded(i) for i in topics["/pioneer/pose"]]
    assert {r["frame_id"] for r in recorded} == {"pioneer/odom"}
    xyth = [(r["pose"]["position"]["x"], r["pose"]["position"]["y"],
             2 * math.atan2(r["pose"]["orientation"]["z"], r["pose"]["orientation"]["w"]))
            for r in recorded]  # fmt: skip
    for x, y, th in poses:
        assert any(abs(x - a) < 1e-9 and abs(y - b) < 1e-9
                   and abs(math.remainder(th - c, 2 * math.pi)) < 1e-9
                   for a, b, c in xyth)  # fmt: skip
    assert poses[-1][0] > 0.01, "the robot drove"
    # the transform odom -> base_link carries the same pose
    tf = decoded(topics["/pioneer/tf"][-1])
    assert (tf["parent_frame_id"], tf["child_frame_id"]) == ("pioneer/odom", "pioneer/base_link")
    # times: log = host receive time in epoch ns; no source clock, so publish = log
    for _, _, message in messages(path):
        assert before <= message.log_time <= after
        assert message.publish_time == message.log_time
    # the sonar scan puts each echo at its distance from base_link: none beyond the sonar's
    # range plus its offset, and some echoes seen in the simulator's room
    scan = decoded(topics["/pioneer/sonar"][-1])
    assert len(scan["ranges"]) == 360 and scan["frame_id"] == "pioneer/base_link"
    assert 0 < sum(r > 0 for r in scan["ranges"]) <= 16
    laser = decoded(topics["/pioneer/laser"][-1])
    assert laser["start_angle"] == pytest.approx(-math.pi / 2)
    assert laser["end_angle"] == pytest.approx(math.pi / 2)
    assert len(laser["ranges"]) == 181


def test_pioneer_raw_channels_are_the_live_dumps_packets(pioneer_url: str,
                                                          tmp_path: Path) -> None:  # fmt: skip
    path = tmp_path / "raw.mcap"
    seen, _, _, _ = _record_pioneer(pioneer_url, path, sips=5)
    raws = {c.topic: c for c in info(path).channels if c.schema == RAW_SCHEMA}
    assert set(raws) == {"/pioneer/raw/tx", "/pioneer/raw/rx"}
    assert {c.encoding for c in raws.values()} == {"json"}  # an encoding every viewer reads
    assert raws["/pioneer/raw/rx"].metadata == {
        "protocol": "arcos", "link": "pioneer", "url": pioneer_url, "direction": "rx"}  # fmt: skip
    # each message: the frame's bytes in base64, with its link, protocol and direction
    for way in ("tx", "rx"):
        sent = [decoded(i) for i in by_topic(path)[f"/pioneer/raw/{way}"]]
        assert {(m["link"], m["protocol"], m["direction"], m["port"]) for m in sent} == {
            ("pioneer", "arcos", way, "")}  # fmt: skip
        assert [base64.b64decode(m["data"]) for m in sent] == [f for d, f in seen if d == way]
    stats = CaptureStats()
    frames = list(read_capture(path, "arcos", stats))
    assert stats.dropped_bytes == 0
    for way in ("tx", "rx"):  # byte for byte, in order, from the handshake to the CLOSE
        assert [f.frame for f in frames if f.direction == way] == [f for d, f in seen if d == way]
    assert frames[0].frame == arcos.frame(b"\x00")  # SYNC0 first
    times = [f.t for f in frames]
    assert times == sorted(times) and times[0] == 0.0


#: Made by robocli before raw channels had a schema (message encoding ``robocli.raw``, the
#: frame's bytes as the message): a Pioneer simulator's session, five SIPs.
OLD_RAW = DATA / "recordings" / "pioneer-robocli-raw.mcap"


def test_raw_channels_of_older_recordings_still_read() -> None:
    raws = {c.topic: c for c in info(OLD_RAW).channels if "/raw/" in c.topic}
    assert {c.encoding for c in raws.values()} == {"robocli.raw"}
    recorded = {way: [i[2].data for i in by_topic(OLD_RAW)[f"/pioneer/raw/{way}"]]
                for way in ("tx", "rx")}  # fmt: skip
    frames = list(read_capture(OLD_RAW, "arcos"))
    for way in ("tx", "rx"):  # the bytes recorded, given back as they are
        assert [f.frame for f in frames if f.direction == way] == recorded[way]
    assert frames[0].frame == arcos.frame(b"\x00") and len(recorded["rx"]) > 5


@pytest.mark.parametrize("compression", ["lz4", "none"])
def test_other_compressions(pioneer_url: str, tmp_path: Path, compression: str) -> None:
    path = tmp_path / f"{compression}.mcap"
    _record_pioneer(pioneer_url, path, sips=3, compression=compression)
    summary = info(path)
    assert summary.compression == ([] if compression == "none" else [compression])
    assert "/pioneer/pose" in {c.topic for c in summary.channels}


def test_arm_joints_frames_and_controller_time(abb: tuple[int, int], tmp_path: Path) -> None:
    path = tmp_path / "arm.mcap"
    motion, state = abb
    seen: list[bytes] = []
    samples: list[Any] = []
    irb = load_model("irb120")
    with Recorder(path) as rec, Arm.connect("127.0.0.1", motion, state) as arm:
        arm.add_listener(lambda d, f, t: seen.append(f) if d == "rx" else None, ports="state")
        arm.add_listener(samples.append, kind="samples")
        # the recorder attaches while frames keep coming: every frame from the end of add()
        # on is recorded, none from before its start (how many fall between is the machine's)
        before_add = len(seen)
        assert rec.add(arm) == "arm"
        after_add, samples_after_add = len(seen), len(samples)
        target = np.radians([20, 10, 5, 0, 30, 10])
        arm.move_to(target, duration=0.5)
        arm.wait_until_idle(20)
        wait_for(
            lambda: sum(s.source == "joint_feedback" for s in samples[samples_after_add:]) > 20,
            "more than 20 joint_feedback samples after the add",
        )
    topics = by_topic(path)
    assert {c: topics[c][0][0].name for c in ("/arm/joint_states", "/arm/joint_feedback",
            "/arm/tcp", "/arm/tf", "/arm/status")} == {
        "/arm/joint_states": "robocli.JointState", "/arm/joint_feedback": "robocli.JointState",
        "/arm/tcp": "foxglove.PoseInFrame", "/arm/tf": "foxglove.FrameTransforms",
        "/arm/status": "robocli.arm.Status"}  # fmt: skip
    feedback = [(decoded(i), i[2]) for i in topics["/arm/joint_feedback"]]
    ours = [s for s in samples if s.source == "joint_feedback"]
    # the samples the client decoded, in order, each on the controller's clock
    recorded = [(tuple(d["position"]), d["robot_time"]) for d, _ in feedback]
    wanted = [(s.joints, s.robot_time) for s in ours]
    assert recorded == wanted[len(wanted) - len(recorded) :] and len(recorded) >= 20
    # publish time: the controller's time plus one offset that only ever shrinks
    offsets = [m.publish_time / 1e9 - d["robot_time"] for d, m in feedback]
    assert all(b <= a + 1e-6 for a, b in zip(offsets, offsets[1:], strict=False))
    assert all(m.publish_time <= m.log_time for _, m in feedback)
    assert max(m.log_time - m.publish_time for _, m in feedback) < 5e9
    # the flange pose and the link frames are the model's forward kinematics
    last_q = feedback[-1][0]["position"]
    tcp = decoded(topics["/arm/tcp"][-1])
    pose = fk(irb, last_q)[0]
    assert [tcp["pose"]["position"][k] for k in "xyz"] == pytest.approx(pose[:3, 3], abs=1e-9)
    tf = decoded(topics["/arm/tf"][-1])
    assert [t["child_frame_id"] for t in tf["transforms"]] == [f"arm/link_{i}"
                                                              for i in range(1, 7)]  # fmt: skip
    assert tf["transforms"][0]["parent_frame_id"] == "arm/base"
    q = tcp["pose"]["orientation"]
    assert sum(v * v for v in q.values()) == pytest.approx(1.0)
    # raw state frames read back as the frames the client received
    captured = list(read_capture(path, "sm-le"))
    frames = [f.frame for f in captured if f.direction == "rx:state"]
    assert frames == seen[len(seen) - len(frames) :]
    assert len(seen) - after_add <= len(frames) <= len(seen) - before_add
    # and the motion port's both ways: the points sent, each acknowledged
    assert {f.direction for f in captured} == {"rx:state", "tx:motion", "rx:motion"}
    sent = [f for f in captured if f.direction == "tx:motion"]
    assert len(sent) == len([f for f in captured if f.direction == "rx:motion"]) >= 2


def test_hub_samples_at_their_acquisition_times(hub_server: HubServer, tmp_path: Path) -> None:
    path = tmp_path / "hub.mcap"
    readings: dict[str, list[Any]] = {}
    with Recorder(path) as rec, Hub.connect(f"127.0.0.1:{hub_server.port}") as hub:
        assert rec.add(hub, sensors=("imu", "adc", "camera", "laser", "gps")) == "hub"
        hub.subscribe("imu", rate=200)
        hub.subscribe("adc", rate=500, channels=0xFF)
        hub.subscribe("camera", rate=10, resolution="160x120")
        hub.subscribe("laser", rate=10)
        hub.subscribe("gps", rate=5)

        def pulled() -> bool:
            for name in ("imu", "adc", "camera", "laser", "gps"):
                reading = hub.read(name)
                if len(reading):
                    readings.setdefault(name, []).append(reading)
            return all(sum(len(r) for r in readings.get(n, [])) >= 3
                       for n in ("imu", "adc", "camera", "laser", "gps"))  # fmt: skip

        wait_for(pulled, what="samples of every sensor")
    topics = by_topic(path)
    for sensor, topic, schema in (("imu", "/hub/imu", "robocli.Imu"),
                                  ("adc", "/hub/adc", "robocli.Adc"),
                                  ("camera", "/hub/camera", "foxglove.RawImage"),
                                  ("laser", "/hub/laser", "foxglove.LaserScan"),
                                  ("gps", "/hub/gps", "foxglove.LocationFix")):  # fmt: skip
        items = topics[topic]
        assert {i[0].name for i in items} == {schema}
        t = np.concatenate([r.t for r in readings[sensor]])
        # one message per sample, published at its acquisition time on this host's clock
        # (through the clock offset the client estimates, which a later pull may refine)
        assert len(items) == len(t)
        published = np.array([i[2].publish_time for i in items]) / 1e9
        assert published == pytest.approx(t, abs=5e-4)
        assert all(i[2].publish_time <= i[2].log_time for i in items)
        for item in items:
            stamp = decoded(item)["timestamp"]
            assert stamp["sec"] * 10**9 + stamp["nsec"] == item[2].publish_time
    imu = decoded(topics["/hub/imu"][0])
    first = readings["imu"][0]
    assert imu["linear_acceleration"]["z"] == pytest.approx(float(first.accel[2, 0]) * 9.80665)
    assert imu["angular_velocity"]["x"] == pytest.approx(math.radians(float(first.gyro[0, 0])))
    adc = decoded(topics["/hub/adc"][0])
    assert adc["channels"] == pytest.approx(readings["adc"][0].data[:, 0].tolist())
    image = decoded(topics["/hub/camera"][0])
    frame = readings["camera"][0].data[..., 0]
    assert (image["width"], image["height"], image["encoding"]) == (160, 120, "rgb8")
    assert base64.b64decode(image["data"]) == frame.tobytes()
    fix = decoded(topics["/hub/gps"][0])
    assert fix["latitude"] == pytest.approx(float(readings["gps"][0].latitude[0]), abs=1e-4)
    scan = decoded(topics["/hub/laser"][0])
    assert len(scan["ranges"]) == readings["laser"][0].data.shape[0]


def test_hub_jpeg_frames_are_compressed_images(hub_server: HubServer, tmp_path: Path) -> None:
    pytest.importorskip("PIL")
    path = tmp_path / "jpeg.mcap"
    with Recorder(path) as rec, Hub.connect(f"127.0.0.1:{hub_server.port}") as hub:
        rec.add(hub)
        hub.subscribe("camera", rate=10, resolution="160x120", quality=80)
        wait_for(lambda: len(hub.read("camera")) > 0, what="a JPEG frame")
    items = by_topic(path)["/hub/camera"]
    image = decoded(items[0])
    assert items[0][0].name == "foxglove.CompressedImage" and image["format"] == "jpeg"
    assert base64.b64decode(image["data"])[:2] == b"\xff\xd8"


def test_several_sources_one_timeline(pioneer_url: str, abb: tuple[int, int],
                                      hub_server: HubServer, tmp_path: Path) -> None:  # fmt: skip
    from robocli.sim.pioneer.server import PioneerSim

    path = tmp_path / "all.mcap"
    with Recorder(path) as rec, PioneerSim("p3dx", time_scale=5.0) as second:
        url2 = second.serve_tcp("127.0.0.1", 0)
        with Pioneer.connect(pioneer_url) as robot, Pioneer.connect(url2) as robot2, \
                Arm.connect("127.0.0.1", *abb, motion=False) as arm, \
                Hub.connect(f"127.0.0.1:{hub_server.port}") as hub:  # fmt: skip
            names = [rec.add(robot), rec.add(robot2), rec.add(arm), rec.add(hub)]
            hub.subscribe("imu", rate=100)
            for _ in range(5):
                robot.wait_for_sip()
                robot2.wait_for_sip()
                hub.read("imu")
    assert names == ["pioneer", "pioneer2", "arm", "hub"]
    summary = info(path)
    prefixes = {c.topic.split("/")[1] for c in summary.channels if c.count}
    assert prefixes == {"pioneer", "pioneer2", "arm", "hub", "robot_description"}
    poses = by_topic(path)["/pioneer2/pose"]
    assert decoded(poses[0])["frame_id"] == "pioneer2/odom"
    times = [m.log_time for _, _, m in messages(path)]
    assert times == sorted(times)  # the reader merges them on the one timeline
    assert summary.start_ns == min(times) and max(times) == summary.end_ns


def test_hub_depth_and_stereo_images(hub_server: HubServer, tmp_path: Path) -> None:
    path = tmp_path / "depth.mcap"
    got: dict[str, Any] = {}
    with Recorder(path) as rec, Hub.connect(f"127.0.0.1:{hub_server.port}") as hub:
        rec.add(hub)
        hub.subscribe("depth", rate=5, resolution="160x120")
        hub.subscribe("stereo", rate=5, resolution="160x120")

        def pulled() -> bool:
            for name in ("depth", "stereo"):
                reading = hub.read(name)
                if len(reading) and name not in got:
                    got[name] = reading
            return len(got) == 2

        wait_for(pulled, what="a depth frame and a stereo pair")
    topics = by_topic(path)
    depth = decoded(topics["/hub/depth/image"][0])
    assert (depth["encoding"], depth["step"], depth["width"]) == ("mono16", 320, 160)
    frame = got["depth"].depth[..., 0]  # H x W uint16, mm
    assert base64.b64decode(depth["data"]) == frame.astype("<u2").tobytes()
    rgb = decoded(topics["/hub/depth/rgb"][0])
    assert base64.b64decode(rgb["data"]) == got["depth"].rgb[..., 0].tobytes()
    for side in ("left", "right"):
        image = decoded(topics[f"/hub/stereo/{side}"][0])
        pixels = getattr(got["stereo"], side)[..., 0]
        assert base64.b64decode(image["data"]) == pixels.tobytes()
