"""The lab's ACL (examples/lab-router.json5) over ROS 2's keys: the bridge r1 publishes its
ROS 2 topics in the namespace /r1 of ROS domain 7; alice, with her own credentials, reads
them, declares her node's graph tokens and drives r1 through /r1/cmd_vel; bob's forged
odometry on r1's topic is dropped by the router."""

from __future__ import annotations

from typing import Any

import numpy as np

from robocli.ros2 import types as T
from robocli.ros2.node import Ros2Node
from robocli.ros2.rmw import Attachment, topic_key
from robocli.sim.pioneer.server import PioneerSim
from tests.ros2.ros2_helpers import robocli_process
from tests.waiting import wait_for
from tests.zenoh.test_lab_acl import Lab, lab  # noqa: F401 - the fixture

ODOM, TWIST = "nav_msgs/msg/Odometry", "geometry_msgs/msg/Twist"


def _forged_odom() -> bytes:
    m = T.message
    pose = m(
        "geometry_msgs/msg/Pose",
        position=m("geometry_msgs/msg/Point", x=0.0, y=0.0, z=0.0),
        orientation=m("geometry_msgs/msg/Quaternion", x=0.0, y=0.0, z=0.0, w=1.0),
    )
    odom = m(ODOM, header=m("std_msgs/msg/Header", frame_id="odom",
                            stamp=m("builtin_interfaces/msg/Time", sec=0, nanosec=0)),
             child_frame_id="forged",
             pose=m("geometry_msgs/msg/PoseWithCovariance", pose=pose, covariance=np.zeros(36)),
             twist=m("geometry_msgs/msg/TwistWithCovariance", twist=_twist(0.0),
                     covariance=np.zeros(36)))  # fmt: skip
    return T.serialize(odom, ODOM)


def _twist(v: float) -> Any:
    vec = T.typestore().types["geometry_msgs/msg/Vector3"]
    return T.message(TWIST, linear=vec(x=v, y=0.0, z=0.0), angular=vec(x=0.0, y=0.0, z=0.0))


def test_the_lab_acl_covers_ros2_topics(lab: Lab) -> None:  # noqa: F811 - the fixture
    with PioneerSim() as simulator:
        url = simulator.serve_tcp("127.0.0.1", 0)
        args = ["bridge", "pioneer", url, "--zenoh", str(lab.configs["r1"]), "--ros2",
                "--ros2-namespace", "/r1", "--ros2-domain", "7"]  # fmt: skip
        with robocli_process(args, "bridge "):
            alice, bob = lab.session("alice"), lab.session("bob")
            try:
                node = Ros2Node(alice, "alice_teleop", domain=7)  # the root namespace: her tokens
                odoms: list[Any] = []
                node.subscriber(
                    "/r1/odom", ODOM, lambda cdr, _a: odoms.append(T.deserialize(cdr, ODOM))
                )
                wait_for(lambda: odoms, "alice reads r1's odometry")
                # bob forges r1's odometry, then probes on his own namespace's key
                key = topic_key(7, "/r1/odom", ODOM, T.type_hash(ODOM))
                probe: list[Any] = []
                alice.declare_subscriber("7/bob/probe", probe.append)
                forged = _forged_odom()
                for _ in range(3):
                    bob.put(key, forged, attachment=Attachment(1, 0, bytes(16)).encode())

                def probed() -> bool:
                    bob.put("7/bob/probe", b"after the forgeries")
                    return bool(probe)

                wait_for(probed, "bob's own put, after his forged ones")
                assert all(o.child_frame_id != "forged" for o in odoms)
                # alice drives r1 through ROS 2 (any lab user may command)
                cmd = node.publisher("/r1/cmd_vel", TWIST)

                def moving() -> bool:
                    cmd.publish(T.serialize(_twist(0.3), TWIST))
                    return simulator.snapshot().trans_vel_set > 0.1

                wait_for(moving, "alice's /r1/cmd_vel moves r1")
                node.close()
            finally:
                alice.close()
                bob.close()
