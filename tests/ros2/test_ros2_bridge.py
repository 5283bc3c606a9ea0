"""``bridge pioneer --ros2``: a simulated Pioneer as a ROS 2 node on a loopback Zenoh router,
seen and driven by zenoh-ros2-sdk (an independent rmw_zenoh implementation) under the
bridge's own controller rules: ROS 2 takes the robot only when it is free, the robot stops
0.5 s after /cmd_vel stops, a set-point re-sent after that stop does not move it until a
zero Twist, a robocli controller is refused while ROS 2 holds it (and ROS 2 ignored while a
robocli controller does), and the robot is released when the ROS 2 publisher leaves."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

from robocli.sim.pioneer.server import PioneerSim
from tests.bridge.bridge_helpers import Events, holder_token, query
from tests.ros2.ros2_helpers import client_config, node_names, robocli_process, router, sdk, topics
from tests.waiting import wait_for

PIONEER_TYPES = {
    "/odom": "nav_msgs/msg/Odometry",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/tf_static": "tf2_msgs/msg/TFMessage",
    "/sonar": "sensor_msgs/msg/LaserScan",
    "/battery": "sensor_msgs/msg/BatteryState",
    "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
    "/robot_description": "std_msgs/msg/String",
    "/cmd_vel": "geometry_msgs/msg/Twist",
}
LATCHED = ":1:,1:,:,:,,"  # rmw_zenoh's QoS chunk of transient local, depth 1


@pytest.fixture
def sim() -> Iterator[tuple[PioneerSim, str]]:
    with PioneerSim() as simulator:
        yield simulator, simulator.serve_tcp("127.0.0.1", 0)


def _moving(simulator: PioneerSim) -> bool:
    return simulator.snapshot().trans_vel_set > 0.1


def _stopped(simulator: PioneerSim) -> bool:
    state = simulator.snapshot()
    return state.trans_vel_set == 0 and state.rot_vel_set == 0


def _twist(z: Any, v: float) -> dict[str, Any]:
    vector = z.get_message_class("geometry_msgs/msg/Vector3")
    return {"linear": vector(x=v, y=0.0, z=0.0), "angular": vector(x=0.0, y=0.0, z=0.0)}


@pytest.fixture
def bridged(sim, tmp_path) -> Iterator[tuple[PioneerSim, Any, int]]:
    with router() as (endpoint, port):
        args = ["bridge", "pioneer", sim[1], "--zenoh", client_config(tmp_path, endpoint),
                "--name", "r1", "--ros2"]  # fmt: skip
        with robocli_process(args, "bridge ") as (_, line), \
                sdk(tmp_path / "msgs", port, list(PIONEER_TYPES.values())) as z:  # fmt: skip
            assert "ROS 2 domain 0" in line
            yield sim[0], z, port


def test_a_bridged_pioneer_is_a_node_whose_topics_zenoh_ros2_sdk_reads(bridged) -> None:
    _, z, port = bridged
    odom: list[Any] = []
    model: list[Any] = []
    z.ROS2Subscriber("/odom", PIONEER_TYPES["/odom"], odom.append, router_port=port)
    found = topics(z, port, set(PIONEER_TYPES))
    for topic, msgtype in PIONEER_TYPES.items():
        assert found.get(topic) == [msgtype], (topic, found)
    assert "/r1" in node_names(z.ZenohSession.get_instance().session)
    wait_for(lambda: len(odom) >= 5, "odometry")
    assert odom[0].header.frame_id == "odom" and odom[0].child_frame_id == "base_link"
    # transient local: a subscriber that joins now still gets the model (the SDK asks the
    # publisher's cache, as rmw_zenoh's subscribers do)
    z.ROS2Subscriber("/robot_description", PIONEER_TYPES["/robot_description"], model.append,
                     router_port=port, qos=LATCHED)  # fmt: skip
    wait_for(lambda: model, "the robot description")
    assert "<robot" in model[0].data and "base_link" in model[0].data


def test_cmd_vel_drives_under_the_controller_rules(bridged) -> None:
    simulator, z, port = bridged
    session = z.ZenohSession.get_instance().session
    events = Events(session, "robocli/r1/@control/event")
    pub = z.ROS2Publisher("/cmd_vel", PIONEER_TYPES["/cmd_vel"], router_port=port)

    def drive(v: float) -> bool:
        pub.publish(**_twist(z, v))
        return _moving(simulator)

    wait_for(lambda: drive(0.3), "the robot moves on /cmd_vel")
    assert query(session, "robocli/r1/@control") == {"holder": "ros2"}
    refused = query(session, "robocli/r1/@control/alice/request", {"op": "acquire"})
    assert refused["granted"] is False and refused["holder"] == "ros2"
    # /cmd_vel stops: the robot stops after the silence (0.5 s)...
    wait_for(lambda: _stopped(simulator), "the robot stops when /cmd_vel stops")
    stop = wait_for(lambda: events.find(event="stopped", holder="ros2"), "a stop event")
    assert "no command" in stop["reason"]
    # ...and the same set-point re-sent does not move it again: a zero Twist comes first
    pub.publish(**_twist(z, 0.3))
    wait_for(lambda: events.find(event="ignored", holder="ros2"), "a stale set-point refused")
    assert _stopped(simulator)
    pub.publish(**_twist(z, 0.0))
    wait_for(lambda: drive(0.3), "the robot moves after a zero Twist")
    # the ROS 2 publisher leaves the graph: the robot is stopped and released
    pub.close()
    wait_for(lambda: _stopped(simulator), "the robot stops when the publisher leaves")
    released = wait_for(lambda: events.find(event="released", holder="ros2"), "the release")
    assert "left" in released["reason"]  # its graph token went, not a timeout
    assert query(session, "robocli/r1/@control") == {"holder": None}


def test_cmd_vel_is_ignored_while_a_robocli_controller_holds_the_robot(bridged) -> None:
    simulator, z, port = bridged
    session = z.ZenohSession.get_instance().session
    events = Events(session, "robocli/r1/@control/event")
    granted = query(session, "robocli/r1/@control/carol/request", {"op": "acquire"})
    assert granted["granted"] is True
    token = holder_token(session, "r1", "carol")
    pub = z.ROS2Publisher("/cmd_vel", PIONEER_TYPES["/cmd_vel"], router_port=port)

    def ignored() -> Any:
        pub.publish(**_twist(z, 0.3))
        return events.find(event="ignored", holder="ros2")

    event = wait_for(ignored, "a ROS 2 command ignored")
    assert "carol does" in event["reason"]
    assert _stopped(simulator)
    assert query(session, "robocli/r1/@control") == {"holder": "carol"}
    token.undeclare()
    pub.close()
