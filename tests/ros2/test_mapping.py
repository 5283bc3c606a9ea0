"""robocli's samples -> ROS 2 messages: every schema of a recording maps to its documented
standard type, in SI units and REP 105 frames, and the CDR decodes back (rosbags' own
deserialiser) to the sample's values."""

from __future__ import annotations

import base64
import math

import numpy as np
import pytest

pytest.importorskip("rosbags")

from robocli.errors import RobocliError
from robocli.io import schemas as S
from robocli.ros2 import RAW_FRAME, Mapper, deserialize, laser_scan_cdr, plain, to_ros2, type_hash

NS = 1_764_000_000_123_456_789
STAMP = S.stamp(NS)


def _decoded(kind: str, topic: str, sample: dict, **kw: bool) -> dict[str, tuple[str, dict]]:
    out = {}
    for m in to_ros2(kind, topic, sample, **kw):
        assert m.data[:4] == b"\x00\x01\x00\x00"  # CDR little-endian encapsulation
        assert m.t_ns == NS
        out[m.topic] = (m.msgtype, plain(deserialize(m.data, m.msgtype)))
    return out


def _state() -> dict:
    return {
        "timestamp": STAMP,
        "x": 1.5,
        "y": -0.25,
        "th": math.pi / 2,
        "v": 0.3,
        "w": -0.1,
        "left_velocity": 0.2,
        "right_velocity": 0.4,
        "battery": 12.6,
        "motors_enabled": True,
        "estop": False,
        "stall_left": True,
        "stall_right": False,
        "bumpers_front": 3,
        "bumpers_rear": 0,
        "sonar": [0.5] * 16,
        "sonar_known": [True] * 16,
        "digin": 1,
        "digout": 0,
        "analog": 1.25,
        "sip_count": 7,
    }


def test_pioneer_state_is_odometry_battery_and_diagnostics() -> None:
    out = _decoded("robocli.pioneer.State", "/pioneer/state", _state())
    kind, odom = out["/pioneer/odom"]
    assert kind == "nav_msgs/msg/Odometry"
    assert odom["header"]["frame_id"] == "odom" and odom["child_frame_id"] == "base_link"
    assert odom["header"]["stamp"] == {"sec": NS // 10**9, "nanosec": NS % 10**9}
    pose = odom["pose"]["pose"]
    assert (pose["position"]["x"], pose["position"]["y"]) == (1.5, -0.25)
    assert pose["orientation"]["z"] == pytest.approx(math.sqrt(0.5))
    assert odom["twist"]["twist"]["linear"]["x"] == 0.3
    assert odom["twist"]["twist"]["angular"]["z"] == -0.1
    kind, battery = out["/pioneer/battery"]
    assert kind == "sensor_msgs/msg/BatteryState"
    assert battery["voltage"] == pytest.approx(12.6) and math.isnan(battery["percentage"])
    kind, diag = out["/diagnostics"]
    assert kind == "diagnostic_msgs/msg/DiagnosticArray"
    status = diag["status"][0]
    assert status["level"] == 1 and status["message"] == "stalled"  # WARN
    values = {v["key"]: v["value"] for v in status["values"]}
    assert values["stall_left"] == "true" and values["bumpers_front"] == "3"


def test_create_state_is_odometry_battery_and_diagnostics() -> None:
    state = {"timestamp": STAMP, "x": 0.5, "y": 0.25, "th": 0.0, "bump_left": False,
             "bump_right": True, "wheel_drop_left": False, "wheel_drop_right": False,
             "voltage": 15.2, "current": -0.4, "charge": 1.5, "capacity": 3.0,
             "charging_state": 0, "mode": 2, "frame_count": 12}  # fmt: skip
    out = _decoded("robocli.create.State", "/create/state", state)
    kind, odom = out["/create/odom"]
    assert kind == "nav_msgs/msg/Odometry" and odom["child_frame_id"] == "base_link"
    assert (odom["pose"]["pose"]["position"]["x"], odom["pose"]["pose"]["position"]["y"]) == (
        0.5,
        0.25,
    )
    assert math.isnan(odom["twist"]["twist"]["linear"]["x"])  # the frame has no velocity
    battery = out["/create/battery"][1]
    assert battery["voltage"] == pytest.approx(15.2) and battery["percentage"] == 0.5
    status = out["/diagnostics"][1]["status"][0]
    assert status["level"] == 1 and status["message"] == "bumped"
    assert {v["key"]: v["value"] for v in status["values"]}["mode"] == "2"


def test_estop_is_an_error_and_a_missing_number_is_nan() -> None:
    state = _state()
    state["estop"] = True
    del state["battery"]  # robocli leaves a number without a value out
    out = _decoded("robocli.pioneer.State", "/p/state", state)
    assert out["/diagnostics"][1]["status"][0]["level"] == 2
    assert math.isnan(out["/p/battery"][1]["voltage"])


def test_transforms_go_to_tf_and_frames_follow_rep105_or_keep_their_prefix() -> None:
    tf = S.frame_transform(NS, "pioneer/odom", "pioneer/base_link", (1.0, 2.0, 0.0),
                           S.quaternion_z(0.5))  # fmt: skip
    kind, msg = _decoded("foxglove.FrameTransform", "/pioneer/tf", tf)["/tf"]
    assert kind == "tf2_msgs/msg/TFMessage"
    (t,) = msg["transforms"]
    assert (t["header"]["frame_id"], t["child_frame_id"]) == ("odom", "base_link")
    assert t["transform"]["translation"] == {"x": 1.0, "y": 2.0, "z": 0.0}
    _, msg = _decoded("foxglove.FrameTransform", "/pioneer/tf", tf, prefix_frames=True)["/tf"]
    assert msg["transforms"][0]["child_frame_id"] == "pioneer/base_link"
    arm = {"transforms": [S.frame_transform(NS, "arm/base", "arm/link_1", (0, 0, 0.29),
                                            S.quaternion_z(0.0)),
                          S.frame_transform(NS, "arm/link_1", "arm/link_2", (0, 0, 0),
                                            S.quaternion_z(0.1))]}  # fmt: skip
    _, msg = _decoded("foxglove.FrameTransforms", "/arm/tf", arm)["/tf"]
    assert [(t["header"]["frame_id"], t["child_frame_id"]) for t in msg["transforms"]] == [
        ("base", "link_1"),
        ("link_1", "link_2"),
    ]  # ROS-Industrial's names


def test_laser_scan_has_ros_conventions() -> None:
    scan = S.laser_scan(NS, "laser/laser", -2.0, 2.0, [1.0, 0.0, 2.5, 40.0, 3.0], [5, 6, 7, 8, 9])
    kind, msg = _decoded("foxglove.LaserScan", "/laser/scan", scan)["/laser/scan"]
    assert kind == "sensor_msgs/msg/LaserScan"
    assert msg["header"]["frame_id"] == "laser"
    assert msg["angle_min"] == -2.0 and msg["angle_max"] == 2.0
    assert msg["angle_increment"] == pytest.approx(1.0)
    assert msg["ranges"][1] == math.inf  # robocli's 0 (no return): +inf (REP 117)
    assert msg["ranges"][3] == 40.0 and msg["range_max"] == 40.0
    assert msg["intensities"] == [5, 6, 7, 8, 9]


@pytest.mark.parametrize("frame", ["l", "ab", "abc", "abcd", "pioneer/base_link"])
@pytest.mark.parametrize("beams", [0, 1, 1081])
def test_fast_laser_scan_bytes_equal_rosbags_serializer(frame: str, beams: int) -> None:
    from robocli.ros2 import serialize
    from robocli.ros2.types import message

    rng = np.random.default_rng(beams)
    ranges = rng.uniform(0.1, 20, beams).astype(np.float32)
    inten = rng.uniform(0, 100, beams).astype(np.float32) if beams % 2 else None
    data = laser_scan_cdr(NS, frame, -2.3, 2.3, ranges, inten)
    back = deserialize(data, "sensor_msgs/msg/LaserScan")
    fields = {k: getattr(back, k) for k in back.__dataclass_fields__ if k[:1].islower()}
    assert serialize(message("sensor_msgs/msg/LaserScan", **fields),
                     "sensor_msgs/msg/LaserScan") == data  # fmt: skip
    assert back.header.frame_id == frame and np.array_equal(back.ranges, ranges)


def test_joint_state_status_and_pose() -> None:
    js = {"timestamp": STAMP, "name": ["joint_1", "joint_2"], "position": [0.1, -0.2],
          "velocity": [], "effort": [], "source": "joint_position"}  # fmt: skip
    kind, msg = _decoded("robocli.JointState", "/arm/joint_states", js)["/arm/joint_states"]
    assert kind == "sensor_msgs/msg/JointState"
    assert msg["name"] == ["joint_1", "joint_2"] and msg["position"] == [0.1, -0.2]
    status = {"timestamp": STAMP, "in_error": True, "mode": "AUTO", "error_code": 5}
    _, diag = _decoded("robocli.arm.Status", "/arm/status", status)["/diagnostics"]
    assert diag["status"][0]["level"] == 2 and diag["status"][0]["name"] == "arm"
    tcp = {"timestamp": STAMP, "frame_id": "arm/base", "pose": S.pose(0.3, 0.0, 0.6)}
    kind, msg = _decoded("foxglove.PoseInFrame", "/arm/tcp", tcp)["/arm/tcp"]
    assert kind == "geometry_msgs/msg/PoseStamped"
    assert msg["header"]["frame_id"] == "base" and msg["pose"]["position"]["z"] == 0.6
    # the Pioneer's pose is in its odometry already
    assert to_ros2("foxglove.PoseInFrame", "/pioneer/pose", dict(tcp)) == []


def test_hub_samples() -> None:
    imu = {"timestamp": STAMP, "frame_id": "hub/imu",
           "linear_acceleration": {"x": 0.0, "y": 0.0, "z": 9.80665},
           "angular_velocity": {"x": 0.1, "y": 0.0, "z": 0.0},
           "magnetic_field": {"x": 2e-5, "y": 0.0, "z": 4e-5}}  # fmt: skip
    out = _decoded("robocli.Imu", "/hub/imu", imu)
    kind, msg = out["/hub/imu"]
    assert kind == "sensor_msgs/msg/Imu" and msg["orientation_covariance"][0] == -1
    assert msg["linear_acceleration"]["z"] == 9.80665 and msg["header"]["frame_id"] == "imu"
    kind, msg = out["/hub/imu/mag"]
    assert kind == "sensor_msgs/msg/MagneticField" and msg["magnetic_field"]["z"] == 4e-5
    adc = {"timestamp": STAMP, "channels": [0.5 * i for i in range(8)]}
    kind, msg = _decoded("robocli.Adc", "/hub/adc", adc)["/hub/adc"]
    assert kind == "std_msgs/msg/Float64MultiArray"
    assert msg["layout"]["dim"] == [{"label": "channel", "size": 8, "stride": 8}]
    assert msg["data"] == adc["channels"]
    bat = {"timestamp": STAMP, "voltage": 11.1, "current": -1.5, "cells": [3.7, 3.7, 3.7],
           "state": 0, "state_of_charge": 0.8}  # fmt: skip
    kind, msg = _decoded("robocli.Battery", "/hub/battery", bat)["/hub/battery"]
    assert kind == "sensor_msgs/msg/BatteryState"
    assert (msg["current"], msg["percentage"]) == (pytest.approx(-1.5), pytest.approx(0.8))
    assert msg["cell_voltage"] == pytest.approx([3.7] * 3)
    sysinfo = {"timestamp": STAMP, "cpu_temperature": 51.0, "load": [0.5, 0.4, 0.3],
               "cpu": {"user": 10.0}, "memory": {"used": 100.0}, "state": 0}  # fmt: skip
    _, diag = _decoded("robocli.SysInfo", "/hub/sysinfo", sysinfo)["/diagnostics"]
    values = {v["key"]: v["value"] for v in diag["status"][0]["values"]}
    assert values == {"cpu_temperature": "51.0", "load": "0.5 0.4 0.3", "cpu.user": "10.0",
                      "memory.used": "100.0", "state": "0"}  # fmt: skip
    fix = S.location_fix(NS, "hub/gps", 46.8, -71.2, 50.0)
    kind, msg = _decoded("foxglove.LocationFix", "/hub/gps", fix)["/hub/gps"]
    assert kind == "sensor_msgs/msg/NavSatFix" and msg["latitude"] == 46.8


def test_images_and_raw_frames_keep_their_bytes() -> None:
    jpeg = S.compressed_image(NS, "hub/camera", b"\xff\xd8jpeg\xff\xd9")
    kind, msg = _decoded("foxglove.CompressedImage", "/hub/camera", jpeg)["/hub/camera"]
    assert kind == "sensor_msgs/msg/CompressedImage"
    assert msg["data"] == b"\xff\xd8jpeg\xff\xd9" and msg["format"] == "jpeg"
    depth = S.raw_image(NS, "hub/depth", 2, 1, "mono16", 4, b"\x01\x02\x03\x04")
    kind, msg = _decoded("foxglove.RawImage", "/hub/depth/image", depth)["/hub/depth/image"]
    assert kind == "sensor_msgs/msg/Image" and msg["encoding"] == "16UC1"
    assert (msg["width"], msg["height"], msg["step"], msg["data"]) == (2, 1, 4, b"\x01\x02\x03\x04")
    raw = {
        "timestamp": STAMP,
        "link": "pioneer",
        "protocol": "arcos",
        "direction": "rx",
        "port": "",
        "data": base64.b64encode(b"\xfa\xfb\x03\x00\x00\x00").decode(),
    }
    kind, msg = _decoded("robocli.RawFrame", "/pioneer/raw/rx", raw)["/pioneer/raw/rx"]
    assert kind == RAW_FRAME and msg["data"] == b"\xfa\xfb\x03\x00\x00\x00"
    assert (msg["link"], msg["protocol"], msg["direction"]) == ("pioneer", "arcos", "rx")


def test_every_recorded_schema_maps_to_ros2() -> None:
    from robocli.ros2.mapping import _HANDLERS

    assert set(S.SCHEMAS) <= set(_HANDLERS), set(S.SCHEMAS) - set(_HANDLERS)
    assert to_ros2("robocli.NotAType", "/x", {}) == []


def test_a_malformed_sample_is_a_typed_error() -> None:
    with pytest.raises(RobocliError, match="does not map"):
        to_ros2("foxglove.LaserScan", "/laser/scan", {"timestamp": STAMP, "ranges": [1.0]})
    with pytest.raises(RobocliError, match="does not decode"):
        deserialize(b"\x00\x01\x00\x00\x05", "sensor_msgs/msg/LaserScan")
    with pytest.raises(RobocliError, match="unknown"):
        deserialize(b"\x00\x01\x00\x00", "nope_msgs/msg/Nope")


def test_type_hashes_are_ros2s() -> None:
    # as ROS 2 Jazzy/Kilted ship them (share/sensor_msgs/msg/LaserScan.json, ...)
    assert type_hash("sensor_msgs/msg/LaserScan") == (
        "RIHS01_64c191398013af96509d518dac71d5164f9382553fce5c1f8cca5be7924bd828"
    )
    assert type_hash(RAW_FRAME).startswith("RIHS01_") and len(type_hash(RAW_FRAME)) == 71


def test_mapper_frames() -> None:
    m = Mapper()
    assert [m.frame(f) for f in ("pioneer/odom", "arm/base", "laser/laser", "odom")] == [
        "odom",
        "base",
        "laser",
        "odom",
    ]
    assert Mapper(prefix_frames=True).frame("arm/base") == "arm/base"


def test_fast_laser_scan_range_max_ignores_infinities_and_nan() -> None:
    ranges = np.array([1.0, np.inf, 45.0, np.nan, 0.0], np.float32)
    back = deserialize(laser_scan_cdr(NS, "laser", -1.0, 1.0, ranges), "sensor_msgs/msg/LaserScan")
    assert back.range_max == 45.0 and back.ranges[4] == np.inf and np.isnan(back.ranges[3])
    small = np.array([np.inf, 2.0], np.float32)
    back = deserialize(laser_scan_cdr(NS, "laser", -1.0, 1.0, small), "sensor_msgs/msg/LaserScan")
    assert back.range_max == 30.0


def test_robot_description_links_follow_the_frames() -> None:
    from robocli.robots.urdf import urdf

    sample = {"data": urdf("irb120", "arm/")}
    (m,) = to_ros2("std_msgs/String", "/arm/robot_description", sample)
    text = plain(deserialize(m.data, m.msgtype))["data"]
    assert m.msgtype == "std_msgs/msg/String"
    assert '<link name="base"' in text and '<child link="link_1"' in text and "arm/" not in text
    (m,) = to_ros2("std_msgs/String", "/arm/robot_description", sample, prefix_frames=True)
    assert plain(deserialize(m.data, m.msgtype))["data"] == sample["data"]
