"""ROS 2 bags from the built-in simulators, read whole by the ecosystem's own readers:
rosbags (AnyReader), mcap-ros2-support (mcap's ROS 2 decoder) and Foxglove's CDR reader
(@foxglove/rosmsg2-serialization, in node: tests/ros2/node, installed by make node-deps).
Bags: a Pioneer with its laser, an arm during an upload (the CLI's upload --record --ros2),
and the full hub (every sensor)."""

from __future__ import annotations

import json
import shutil
import subprocess
from collections import Counter
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("rosbags")
pytest.importorskip("mcap_ros2")

from robocli.io.record import info

NODE_DIR = Path(__file__).parent / "node"

#: What each bag holds at least: topic -> type.
EXPECTED = {
    "pioneer": {
        "/pioneer/odom": "nav_msgs/msg/Odometry", "/tf": "tf2_msgs/msg/TFMessage",
        "/pioneer/sonar": "sensor_msgs/msg/LaserScan",
        "/pioneer/laser": "sensor_msgs/msg/LaserScan",
        "/pioneer/battery": "sensor_msgs/msg/BatteryState",
        "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
        "/pioneer/raw/rx": "robocli_msgs/msg/RawFrame",
        "/pioneer/raw/tx": "robocli_msgs/msg/RawFrame",
        "/pioneer/robot_description": "std_msgs/msg/String",
        "/robot_description": "std_msgs/msg/String",
    },
    "arm": {
        "/arm/joint_states": "sensor_msgs/msg/JointState",
        "/arm/joint_feedback": "sensor_msgs/msg/JointState",
        "/arm/tcp": "geometry_msgs/msg/PoseStamped", "/tf": "tf2_msgs/msg/TFMessage",
        "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
        "/arm/raw/motion/tx": "robocli_msgs/msg/RawFrame",
        "/arm/raw/motion/rx": "robocli_msgs/msg/RawFrame",
        "/arm/raw/state/rx": "robocli_msgs/msg/RawFrame",
        "/arm/robot_description": "std_msgs/msg/String",
    },
    "hub": {
        "/hub/imu": "sensor_msgs/msg/Imu", "/hub/imu/mag": "sensor_msgs/msg/MagneticField",
        "/hub/adc": "std_msgs/msg/Float64MultiArray", "/hub/laser": "sensor_msgs/msg/LaserScan",
        "/hub/gps": "sensor_msgs/msg/NavSatFix", "/hub/camera": "sensor_msgs/msg/Image",
        "/hub/battery": "sensor_msgs/msg/BatteryState",
        "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
        "/hub/depth/image": "sensor_msgs/msg/Image", "/hub/depth/rgb": "sensor_msgs/msg/Image",
        "/hub/stereo/left": "sensor_msgs/msg/Image",
        "/hub/stereo/right": "sensor_msgs/msg/Image",
        "/hub/raw/rx": "robocli_msgs/msg/RawFrame", "/hub/raw/tx": "robocli_msgs/msg/RawFrame",
    },
}  # fmt: skip


def _rosbags(path: Path) -> tuple[dict[str, str], Counter[str], dict[str, Any]]:
    """(type by topic, messages by topic, first message by topic) as rosbags reads them."""
    from rosbags.highlevel import AnyReader

    types: dict[str, str] = {}
    counts: Counter[str] = Counter()
    first: dict[str, Any] = {}
    with AnyReader([path]) as reader:
        for conn in reader.connections:
            types[conn.topic] = conn.msgtype
        for conn, _t, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            counts[conn.topic] += 1
            first.setdefault(conn.topic, msg)
    return types, counts, first


SOURCES = ["pioneer", "arm", "hub"]


@pytest.mark.parametrize("source", SOURCES)
def test_rosbags_reads_the_bag_whole(bags: dict[str, Path], source: str) -> None:
    path = bags[source]
    types, counts, first = _rosbags(path)
    assert {t: types.get(t) for t in EXPECTED[source]} == EXPECTED[source]
    assert all(counts[t] for t in EXPECTED[source]), counts
    assert sum(counts.values()) == info(path).messages
    if source == "pioneer":
        odom = first["/pioneer/odom"]
        assert (odom.header.frame_id, odom.child_frame_id) == ("odom", "base_link")
        assert len(first["/pioneer/laser"].ranges) == 181
    elif source == "arm":
        assert list(first["/arm/joint_states"].name) == [f"joint_{i}" for i in range(1, 7)]
    if source != "hub":  # the model's links are the frames /tf moves (REP 105 names)
        import re

        links = set(re.findall(r'<link name="([^"]+)"', first[f"/{source}/robot_description"].data))
        frames = {f for t in first["/tf"].transforms for f in (t.header.frame_id, t.child_frame_id)}
        assert frames - {"odom"} <= links, (frames, links)
    else:
        assert (first["/hub/camera"].width, first["/hub/camera"].encoding) == (160, "rgb8")
        assert first["/hub/depth/image"].encoding == "16UC1"


@pytest.mark.parametrize("source", SOURCES)
def test_mcap_ros2_support_decodes_every_message(bags: dict[str, Path], source: str) -> None:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    path = bags[source]
    counts: Counter[str] = Counter()
    with path.open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == "ros2"
        for schema, channel, _message, decoded in reader.iter_decoded_messages():
            assert (schema.encoding, channel.message_encoding) == ("ros2msg", "cdr")
            assert "offered_qos_profiles" in channel.metadata
            assert channel.metadata["topic_type_hash"].startswith("RIHS01_")
            assert decoded is not None
            counts[channel.topic] += 1
        records = {m.name: m.metadata for m in reader.iter_metadata()}
    assert sum(counts.values()) == info(path).messages
    # the rosbag2 record: its topics and counts are the file's
    from ruamel.yaml import YAML

    meta = YAML(typ="safe").load(records["rosbag2"]["serialized_metadata"])
    assert meta["storage_identifier"] == "mcap" and meta["message_count"] == sum(counts.values())
    assert {t["topic_metadata"]["name"]: t["message_count"]
            for t in meta["topics_with_message_count"]} == dict(counts)  # fmt: skip


def _node_decode(path: Path) -> dict[str, Any]:
    node = shutil.which("node")
    if node is None:
        pytest.skip("node is not installed: Foxglove's CDR reader cannot run")
    if not (NODE_DIR / "node_modules" / "@foxglove" / "rosmsg2-serialization").is_dir():
        pytest.skip("tests/ros2/node/node_modules is missing: run make node-deps (npm)")
    proc = subprocess.run([node, str(NODE_DIR / "decode_bag.js"), str(path)],
                          capture_output=True, text=True, timeout=120)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    out: dict[str, Any] = json.loads(proc.stdout)
    return out


@pytest.mark.parametrize("source", SOURCES)
def test_foxglove_decodes_every_message(bags: dict[str, Path], source: str) -> None:
    path = bags[source]
    got = _node_decode(path)
    types, counts, first = _rosbags(path)
    assert got["profile"] == "ros2"
    assert {t: v["count"] for t, v in got["topics"].items()} == dict(counts)
    assert {t: v["type"] for t, v in got["topics"].items()} == types
    assert {v["encoding"] for v in got["topics"].values()} == {"cdr"}
    # the same values as rosbags decodes
    for topic, msg in first.items():
        fox = got["first"][topic]
        if types[topic] == "sensor_msgs/msg/LaserScan":
            assert [float(v) for v in fox["ranges"]] == msg.ranges.tolist()  # inf: "Infinity"
        elif types[topic] == "nav_msgs/msg/Odometry":
            assert fox["pose"]["pose"]["position"]["x"] == msg.pose.pose.position.x
        elif types[topic] == "robocli_msgs/msg/RawFrame":
            assert bytes(fox["data"]) == bytes(msg.data)
        elif types[topic] == "sensor_msgs/msg/JointState":
            assert fox["position"] == msg.position.tolist()
        if "header" in fox:  # (Foxglove names a Time's fields sec and nsec)
            assert fox["header"]["stamp"] == {"sec": msg.header.stamp.sec,
                                              "nsec": msg.header.stamp.nanosec}  # fmt: skip
