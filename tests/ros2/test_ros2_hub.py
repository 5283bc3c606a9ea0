"""``serve --zenoh --ros2``: the hub is a ROS 2 node on a loopback Zenoh router, and
zenoh-ros2-sdk (an independent rmw_zenoh implementation, which computes the type hashes
itself from the .msg files) lists its node and topics and receives its messages, one per
sample, while robocli's own keys go on beside them."""

from __future__ import annotations

import math
import time

from tests.ros2.ros2_helpers import (
    client_config,
    node_names,
    robocli_process,
    router,
    sdk,
    topics,
)
from tests.waiting import wait_for

HUB_TYPES = {
    "/adc": "std_msgs/msg/Float64MultiArray",
    "/imu": "sensor_msgs/msg/Imu",
    "/imu/mag": "sensor_msgs/msg/MagneticField",
    "/gps": "sensor_msgs/msg/NavSatFix",
    "/battery": "sensor_msgs/msg/BatteryState",
    "/diagnostics": "diagnostic_msgs/msg/DiagnosticArray",
}


def _stamp(msg: object) -> float:
    stamp = msg.header.stamp  # type: ignore[attr-defined]
    return float(stamp.sec + stamp.nanosec * 1e-9)


def test_a_hub_serving_ros2_is_a_node_whose_topics_zenoh_ros2_sdk_reads(tmp_path) -> None:
    with router() as (endpoint, port):
        args = ["serve", "--sim", "--no-tcp", "--zenoh", client_config(tmp_path, endpoint),
                "--name", "hub1", "--ros2"]  # fmt: skip
        with robocli_process(args, "hub ") as (_, line), \
                sdk(tmp_path / "msgs", port, list(HUB_TYPES.values())) as z:  # fmt: skip
            assert "ROS 2 domain 0" in line
            imu: list[object] = []
            adc: list[object] = []
            z.ROS2Subscriber("/imu", HUB_TYPES["/imu"], imu.append, router_port=port)
            z.ROS2Subscriber("/adc", HUB_TYPES["/adc"], adc.append, router_port=port)
            found = topics(z, port, set(HUB_TYPES))
            for topic, msgtype in HUB_TYPES.items():
                assert found.get(topic) == [msgtype], (topic, found)
            session = z.ZenohSession.get_instance().session
            assert "/hub1" in node_names(session)
            wait_for(lambda: len(imu) >= 20 and len(adc) >= 20, "20 IMU and ADC messages")
            stamps = [_stamp(m) for m in imu[:20]]
            assert all(b > a for a, b in zip(stamps, stamps[1:], strict=False)), "one per sample"
            assert abs(stamps[-1] - time.time()) < 60  # the hub's clock mapped onto Unix time
            first = imu[0]
            assert first.header.frame_id == "imu"  # type: ignore[attr-defined]
            assert math.isfinite(first.linear_acceleration.z)  # type: ignore[attr-defined]
            assert [d.label for d in adc[0].layout.dim] == ["channel"]  # type: ignore[attr-defined]
            assert len(adc[0].data) == 8  # type: ignore[attr-defined]
            batches: list[bytes] = []  # robocli's own keys go on beside ROS 2's
            sub = session.declare_subscriber(
                "robocli/hub1/adc", lambda s: batches.append(s.payload.to_bytes())
            )
            wait_for(lambda: batches, "a batch on robocli/hub1/adc")
            sub.undeclare()


def test_a_sensor_nobody_reads_on_ros2_is_not_decoded_until_someone_does(endpoint) -> None:
    """The hub's first ADC batch declares /adc; with no ROS 2 subscriber the next batches
    are skipped (robocli's own key still gets them), and a subscriber brings them back."""
    from robocli.hub_server import HubServer
    from robocli.hub_server.frontends.ros2 import HubTopics
    from robocli.hub_server.frontends.zenoh import ZenohFrontend
    from robocli.ros2.rmw import topic_key
    from robocli.ros2.types import type_hash
    from robocli.zenoh.session import close_session, open_session

    server = HubServer(port=0, sim=True).start()
    session = open_session(endpoint, "server")
    front = ZenohFrontend(server.hub, session, "hub1", publish={"adc": None})
    ros = HubTopics(server.hub, session, "hub1")
    front.on_batch = ros.batch
    front.start()
    reader = open_session(endpoint, "client")
    try:
        wait_for(lambda: ros.skipped >= 3, "ADC batches skipped with no ROS 2 subscriber")
        published = ros.topics.published
        key = topic_key(0, "/adc", HUB_TYPES["/adc"], type_hash(HUB_TYPES["/adc"]))
        got: list[object] = []
        reader.declare_subscriber(key, got.append)
        wait_for(lambda: len(got) >= 10, "ADC messages once a ROS 2 subscriber is there")
        assert ros.topics.published > published
    finally:
        front.close()
        ros.close()
        close_session(reader)
        close_session(session)
        server.close()


def test_ros2_without_zenoh_is_a_one_line_usage_error() -> None:
    from tests.zenoh.test_cli_zenoh import robocli

    done = robocli("serve", "--sim", "--no-tcp", "--ros2")
    assert done.returncode == 2  # --no-tcp without --zenoh: the first usage error
    done = robocli("serve", "--sim", "--port", "0", "--ros2")
    assert done.returncode == 2 and "--ros2" in done.stderr and "Traceback" not in done.stderr
