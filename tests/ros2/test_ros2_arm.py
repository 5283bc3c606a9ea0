"""``bridge arm --ros2``: a simulated IRB120 as a ROS 2 node on a loopback router. zenoh-ros2-
sdk reads its joint states and its model, and its JointTrajectory on joint_trajectory is run
under the bridge's controller rules (ROS 2 takes the free arm; the points are checked and
downloaded as a robocli upload is)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from robocli.sim.abb.server import AbbSim
from tests.bridge.bridge_helpers import Events, query
from tests.ros2.ros2_helpers import client_config, robocli_process, router, sdk, topics
from tests.waiting import wait_for

ARM_TYPES = {
    "/joint_states": "sensor_msgs/msg/JointState",
    "/robot_description": "std_msgs/msg/String",
    "/joint_trajectory": "trajectory_msgs/msg/JointTrajectory",
}


@pytest.fixture
def bridged(tmp_path) -> Iterator[tuple[AbbSim, Any, int]]:
    with AbbSim("irb120", state_ms=20) as simulator, router() as (endpoint, port):
        motion, state = simulator.serve_tcp("127.0.0.1", 0, 0)
        args = ["bridge", "arm", "127.0.0.1", "--motion-port", motion.rsplit(":", 1)[1],
                "--state-port", state.rsplit(":", 1)[1], "--zenoh",
                client_config(tmp_path, endpoint), "--name", "a1", "--ros2"]  # fmt: skip
        with robocli_process(args, "bridge "), \
                sdk(tmp_path / "msgs", port, list(ARM_TYPES.values())) as z:  # fmt: skip
            yield simulator, z, port


def test_a_joint_trajectory_on_ros2_moves_the_bridged_arm(bridged) -> None:
    simulator, z, port = bridged
    states: list[Any] = []
    z.ROS2Subscriber("/joint_states", ARM_TYPES["/joint_states"], states.append,
                     router_port=port)  # fmt: skip
    found = topics(z, port, set(ARM_TYPES))
    for topic, msgtype in ARM_TYPES.items():
        assert found.get(topic) == [msgtype], (topic, found)
    wait_for(lambda: states, "joint states")
    assert list(states[-1].name) == [f"joint_{i}" for i in range(1, 7)]
    q0 = [float(v) for v in states[-1].position]
    session = z.ZenohSession.get_instance().session
    events = Events(session, "robocli/a1/@control/event")
    point = z.get_message_class("trajectory_msgs/msg/JointTrajectoryPoint")
    duration = z.get_message_class("builtin_interfaces/msg/Duration")
    header = z.get_message_class("std_msgs/msg/Header")
    stamp = z.get_message_class("builtin_interfaces/msg/Time")
    pub = z.ROS2Publisher("/joint_trajectory", ARM_TYPES["/joint_trajectory"], router_port=port)
    goal = [q0[0] + 0.2, *q0[1:]]
    names = [f"joint_{i}" for i in (2, 1, 3, 4, 5, 6)]  # any order: mapped by name

    def as_named(q: list[float]) -> Any:
        return np.array([q[1], q[0], *q[2:]], dtype=float)

    empty = np.zeros(0)
    points = [point(positions=as_named(q), velocities=empty, accelerations=empty,
                    effort=empty, time_from_start=duration(sec=s, nanosec=0))
              for q, s in ((q0, 0), (goal, 1))]  # fmt: skip
    msg = {"header": header(stamp=stamp(sec=0, nanosec=0), frame_id=""), "joint_names": names,
           "points": points}  # fmt: skip

    def sent() -> Any:
        pub.publish(**msg)
        return events.find(event="granted", holder="ros2")

    wait_for(sent, "ROS 2 takes the arm")
    wait_for(lambda: simulator.snapshot().trajectories >= 1, "the trajectory downloaded")
    wait_for(lambda: abs(float(states[-1].position[0]) - goal[0]) < 1e-3, "the arm at its goal")
    assert query(session, "robocli/a1/@control") == {"holder": "ros2"}
    pub.close()
