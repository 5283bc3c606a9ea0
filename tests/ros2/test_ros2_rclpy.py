"""Optional: ROS 2's own rclpy decodes the CDR a bridged Pioneer publishes with ``--ros2``
(``rclpy.serialization.deserialize_message``, from the ``ros-rclpy`` wheels of ROS 2 Kilted),
to the same values as rosbags. rclpy is never a dependency: give the Python of a venv of
its own that has it, as ``ROBOCLI_RCLPY_PYTHON``::

    python3.11 -m venv /tmp/rclpy-venv
    /tmp/rclpy-venv/bin/pip install ros-rclpy ros-rmw-fastrtps-cpp ros-nav-msgs \\
        ros-geometry-msgs ros-std-msgs ros-sensor-msgs ros-diagnostic-msgs
    ROBOCLI_RCLPY_PYTHON=/tmp/rclpy-venv/bin/python pytest tests/ros2/test_ros2_rclpy.py

Skipped at once, with its reason, where the variable is not set or rclpy does not import
there (without an rmw implementation wheel it does not: librmw_fastrtps_cpp.so). tf2_msgs
has no wheel: its messages are left to rosbags' checks. Installing the wheels takes
minutes: they are not part of make test."""

from __future__ import annotations

import json
import os
import subprocess

import pytest

from robocli.ros2 import types as T
from robocli.ros2.rmw import Attachment, parse_token
from robocli.sim.pioneer.server import PioneerSim
from tests.ros2.ros2_helpers import client_config, robocli_process, router
from tests.waiting import wait_for

_DECODE = """
import importlib, json, sys
from rclpy.serialization import deserialize_message
out = {}
for msgtype, hexdata in json.load(sys.stdin).items():
    pkg, _, name = msgtype.split("/")
    try:
        cls = getattr(importlib.import_module(pkg + ".msg"), name)
    except ImportError:  # a package of which no wheel is installed (tf2_msgs has none)
        out[msgtype] = None
        continue
    msg = deserialize_message(bytes.fromhex(hexdata), cls)
    if msgtype == "nav_msgs/msg/Odometry":
        out[msgtype] = [msg.header.frame_id, msg.child_frame_id, msg.pose.pose.orientation.w]
    elif msgtype == "std_msgs/msg/String":
        out[msgtype] = [msg.data[:200]]
    else:
        out[msgtype] = [type(msg).__name__]
print(json.dumps(out))
"""


def _rclpy_python() -> str:
    python = os.environ.get("ROBOCLI_RCLPY_PYTHON")
    if not python:
        pytest.skip("ROBOCLI_RCLPY_PYTHON is not set (a venv with the ros-rclpy wheels)")
    try:
        done = subprocess.run([python, "-c", "import rclpy.serialization"], capture_output=True,
                              text=True, timeout=300)  # fmt: skip
    except (OSError, subprocess.TimeoutExpired) as exc:
        pytest.skip(f"{python} does not run: {exc}")
    if done.returncode != 0:
        pytest.skip(f"rclpy does not import in {python}: {done.stderr.strip()[-300:]}")
    return python


def test_rclpy_decodes_what_a_bridged_pioneer_publishes(tmp_path) -> None:
    python = _rclpy_python()
    from robocli.zenoh.session import close_session, open_session

    with PioneerSim() as simulator, router() as (endpoint, _port):
        url = simulator.serve_tcp("127.0.0.1", 0)
        config = client_config(tmp_path, endpoint)
        with robocli_process(["bridge", "pioneer", url, "--zenoh", config, "--ros2"], "bridge "):
            session = open_session(config, "client")
            samples: dict[str, tuple[bytes, bytes | None]] = {}
            types: dict[str, str] = {}
            try:

                def keep(sample: object) -> None:
                    dds = str(sample.key_expr).split("/")[-2]  # type: ignore[attr-defined]
                    raw = sample.attachment  # type: ignore[attr-defined]
                    samples.setdefault(
                        dds,
                        (
                            sample.payload.to_bytes(),  # type: ignore[attr-defined]
                            None if raw is None else raw.to_bytes(),
                        ),
                    )

                session.declare_subscriber("0/**", keep)
                wanted = {"nav_msgs::msg::dds_::Odometry_", "tf2_msgs::msg::dds_::TFMessage_"}
                wait_for(lambda: wanted <= set(samples), "odometry and tf samples")
                for reply in session.liveliness().get("@ros2_lv/0/**", timeout=5.0):
                    if reply.ok is not None:
                        token = parse_token(str(reply.ok.key_expr))
                        if token.kind == "MP" and token.dds_type:
                            pkg, kind, _, name = token.dds_type.split("::")
                            types[token.dds_type] = f"{pkg}/{kind}/{name[:-1]}"
            finally:
                close_session(session)
    cdr = {types[d]: data.hex() for d, (data, _) in samples.items() if d in types}
    for _, attachment in samples.values():
        Attachment.decode(attachment)  # every sample carries rmw_zenoh's attachment
    done = subprocess.run([python, "-c", _DECODE], input=json.dumps(cdr), capture_output=True,
                          text=True, timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    decoded = json.loads(done.stdout.strip().splitlines()[-1])
    odom = T.deserialize(bytes.fromhex(cdr["nav_msgs/msg/Odometry"]), "nav_msgs/msg/Odometry")
    assert decoded["nav_msgs/msg/Odometry"] == [odom.header.frame_id, odom.child_frame_id,
                                                odom.pose.pose.orientation.w]  # fmt: skip
    assert set(decoded) == set(cdr)
    assert decoded["sensor_msgs/msg/LaserScan"] == ["LaserScan"]  # the sonar ring
