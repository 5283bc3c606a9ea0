"""A bridged robot as a ROS 2 node on Zenoh (``bridge pioneer|arm --ros2``), beside its
robocli keys, as ``rmw_zenoh_cpp`` would show it (:mod:`robocli.ros2.node`).

**Out**: the same messages as a ROS 2 bag of the robot (the recorder's decoders, then
:mod:`robocli.ros2.mapping`, through :class:`~robocli.ros2.live.Ros2Topics`): a Pioneer's
``odom``, ``tf``, ``sonar``, ``laser``, ``battery``, ``diagnostics``; an arm's
``joint_states``, ``tcp``, ``tf``, ``diagnostics``; and ``robot_description`` (the URDF,
std_msgs/String) and ``tf_static`` (its fixed joints), both transient local.

**In**, under the bridge's :class:`~robocli.bridge.control.ControlGate`, unchanged:

* a Pioneer subscribes to ``cmd_vel`` (geometry_msgs/Twist: ``linear.x`` m/s, ``angular.z``
  rad/s); an arm to ``joint_trajectory`` (trajectory_msgs/JointTrajectory: its points'
  ``positions`` in rad, ``time_from_start``; joint names, when given, in any order of
  ``joint_1``...).
* Every ROS 2 publisher of those topics is one controller named :data:`ROS_HOLDER`
  (``ros2``). A ROS 2 command takes the robot **only when nobody holds it** and a publisher
  of the topic is in the ROS 2 graph (a message still in flight after its publisher left
  takes nothing): a robocli
  controller that holds it is never preempted (the ROS 2 command is ignored, counted, and
  announced once on ``robocli/<robot>/@control/event``), and a robocli controller asking
  while ROS 2 holds it is refused with the holder's name ``ros2``.
* ROS 2 holds the robot while at least one publisher of the command topic is in the ROS 2
  graph (its ``MP`` liveliness token, the rmw_zenoh way): when the last one leaves (its node
  ended or crashed, its link broke), the robot is stopped and released, as when a robocli
  controller's token goes.
* The gate's stop rules apply as they are: a moving robot is stopped when ``cmd_vel`` stops
  for the bridge's ``--silence`` (0.5 s); after any stop the bridge made (silence, a stall
  past the robot's watchdog, a release) a ROS 2 publisher **sends a zero Twist before it
  moves the robot again** (a Twist carries no epoch: the gate's rule for commands without
  one), so a set-point that a stalled node re-sends never resumes motion.

Under the lab's ACL (:mod:`robocli.zenoh.acl`), any lab user may publish these two command
topics (the router checks who they are; ROS 2 has no name of its own to check), and only
the robot's own user may publish its other topics.
"""

from __future__ import annotations

import contextlib
import logging
import math
import threading
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import numpy as np

from robocli.errors import ProtocolError, RobocliError
from robocli.ros2 import types as T
from robocli.ros2.live import Ros2Topics
from robocli.ros2.node import Ros2Node, node_name
from robocli.ros2.rmw import Attachment, dds_type, domain_keys, parse_token
from robocli.zenoh.session import import_zenoh

if TYPE_CHECKING:
    import zenoh

    from robocli.bridge.arm import ArmBridge
    from robocli.bridge.control import ControlGate
    from robocli.bridge.pioneer import PioneerBridge

__all__ = ["ROS_HOLDER", "Ros2Bridge", "ros2_arm", "ros2_node", "ros2_pioneer", "trajectory_arrays"]

log = logging.getLogger("robocli.bridge")

ROS_HOLDER = "ros2"
"""The one controller name every ROS 2 publisher of a command topic drives as."""
MAX_PUBLISHERS = 1024
"""The most ROS 2 publishers of the command topics a bridge keeps track of."""


class Ros2Bridge:
    """The ROS 2 node of a bridged robot named ``name`` (see the module)."""

    def __init__(self, session: zenoh.Session, name: str, gate: ControlGate, *,
                 domain: int = 0, namespace: str = "") -> None:  # fmt: skip
        self.gate = gate
        self.node = Ros2Node(session, node_name(name), namespace=namespace, domain=domain)
        self.topics = Ros2Topics(self.node, name)
        self.bad_commands = 0
        self._commands: dict[str, str] = {}  # a command topic (qualified) -> its DDS type
        self._publishers: set[str] = set()  # the graph tokens of their ROS 2 publishers
        self._lock = threading.Lock()
        z = import_zenoh()
        self._put = z.SampleKind.PUT
        self._graph = session.liveliness().declare_subscriber(
            domain_keys(domain), self._on_graph, history=True
        )

    def command(self, topic: str, ros_type: str, handle: Any) -> None:
        """Subscribe ``topic``: ``handle(message)`` per command, on Zenoh's thread."""
        what = f"{self.node.name} {topic}"

        def on_message(cdr: bytes, _attachment: Attachment) -> None:
            try:
                msg = T.deserialize(cdr, ros_type)
                handle(msg)
            except (RobocliError, ValueError) as exc:
                self.bad_commands += 1
                if self.bad_commands == 1:
                    log.warning("%s: %s (later ones only counted)", what, exc)
                    self.gate.event("ignored", holder=self.gate.holder,
                                    reason=f"{what}: {exc}")  # fmt: skip

        with self._lock:
            self._commands[self.node.resolve(topic)] = dds_type(ros_type)
        self.node.subscriber(topic, ros_type, on_message)

    def take(self) -> bool:
        """Before a ROS 2 command: take the robot for :data:`ROS_HOLDER` when nobody holds
        it and a ROS 2 publisher of a command topic is in the graph (a sample still in
        flight when its publisher left takes nothing: the robot stays stopped). True when
        ROS 2 holds it (the gate still judges each command)."""
        with self._lock:
            present = bool(self._publishers)
        if self.gate.holder is None and present:
            self.gate.acquire(ROS_HOLDER)
        return self.gate.holder == ROS_HOLDER

    def _on_graph(self, sample: zenoh.Sample) -> None:
        """Count the ROS 2 publishers of the command topics (their MP tokens)."""
        key = str(sample.key_expr)
        try:
            token = parse_token(key)
        except ProtocolError:
            return
        if token.kind != "MP" or token.zid == self.node.zid:
            return
        with self._lock:
            if self._commands.get(token.topic or "") != token.dds_type:
                return
            before = bool(self._publishers)
            if sample.kind == self._put:
                if len(self._publishers) >= MAX_PUBLISHERS:
                    return  # a flood of tokens: the ones known keep ROS 2 holding
                self._publishers.add(key)
            else:
                self._publishers.discard(key)
            after = bool(self._publishers)
        if before != after:
            self.gate.alive(ROS_HOLDER, after)

    def close(self) -> None:
        """Undeclare the graph watch, the node's topics and the node. Idempotent."""
        from robocli.zenoh.robot_keys import undeclare

        undeclare(self._graph)
        self.topics.close()
        self.node.close()


def ros2_pioneer(bridge: PioneerBridge, session: zenoh.Session, *, domain: int = 0,
                 namespace: str = "") -> Ros2Bridge:  # fmt: skip
    """``bridge``'s Pioneer as a ROS 2 node (see the module)."""
    from robocli.io.record.pioneer import attach_pioneer
    from robocli.robots.urdf import urdf

    ros = Ros2Bridge(session, bridge.name, bridge.gate, domain=domain, namespace=namespace)
    attach_pioneer(ros.topics, bridge.robot, bridge.name)
    ros.topics.publish_static(urdf(bridge.robot.params.subtype))

    def twist(msg: Any) -> None:
        v, w = float(msg.linear.x), float(msg.angular.z)
        if not (math.isfinite(v) and math.isfinite(w)):
            raise ProtocolError(f"a Twist of {v!r} m/s, {w!r} rad/s")
        ros.take()
        bridge.drive(ROS_HOLDER, v, w)

    ros.command("cmd_vel", "geometry_msgs/msg/Twist", twist)
    return ros


def ros2_arm(bridge: ArmBridge, session: zenoh.Session, *, domain: int = 0,
             namespace: str = "") -> Ros2Bridge:  # fmt: skip
    """``bridge``'s arm as a ROS 2 node (see the module)."""
    from robocli.io.record.arm import attach_arm
    from robocli.robots.urdf import urdf

    ros = Ros2Bridge(session, bridge.name, bridge.gate, domain=domain, namespace=namespace)
    attach_arm(ros.topics, bridge.arm, bridge.name, ports="state")
    ros.topics.publish_static(urdf(bridge.arm.robot.name))
    n = bridge.arm.robot.n_joints
    names = [f"joint_{i + 1}" for i in range(n)]

    def trajectory(msg: Any) -> None:
        times, joints = trajectory_arrays(msg, names)
        ros.take()

        def upload() -> None:
            try:
                bridge.upload(ROS_HOLDER, times, joints)
            except RobocliError as exc:
                bridge.gate.event("ignored", holder=bridge.gate.holder,
                                  reason=f"ROS 2 trajectory: {exc}")  # fmt: skip

        if not bridge.queue_work(upload):
            raise ProtocolError("busy with other uploads")

    ros.command("joint_trajectory", "trajectory_msgs/msg/JointTrajectory", trajectory)
    return ros


def trajectory_arrays(msg: Any, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """(times s, joints rad N x n) of a JointTrajectory whose joints are ``names`` (in any
    order when it names them); :class:`ProtocolError` for anything else."""
    given = list(msg.joint_names) or names
    if sorted(given) != sorted(names):
        raise ProtocolError(f"joint_names {given[:8]} are not {names}")
    order = [given.index(n) for n in names]
    if not msg.points:
        raise ProtocolError("a trajectory without points")
    times = np.array([p.time_from_start.sec + p.time_from_start.nanosec * 1e-9
                      for p in msg.points], dtype=float)  # fmt: skip
    try:
        joints = np.array([[float(p.positions[i]) for i in order] for p in msg.points])
    except IndexError:
        raise ProtocolError(f"a point has fewer than {len(names)} positions") from None
    if not (np.isfinite(times).all() and np.isfinite(joints).all()):
        raise ProtocolError("a trajectory of numbers that are not finite")
    return times, joints


@contextlib.contextmanager
def ros2_node(bridge: PioneerBridge | ArmBridge, session: zenoh.Session, enabled: bool, *,
              domain: int = 0, namespace: str = "") -> Iterator[Ros2Bridge | None]:  # fmt: skip
    """``bridge`` as a ROS 2 node while the block runs (``enabled`` False: None, nothing)."""
    from robocli.bridge.pioneer import PioneerBridge

    if not enabled:
        yield None
        return
    make = ros2_pioneer if isinstance(bridge, PioneerBridge) else ros2_arm
    ros = make(bridge, session, domain=domain, namespace=namespace)  # type: ignore[arg-type]
    try:
        yield ros
    finally:
        ros.close()
