"""The arm's channels: joint states, the flange pose and every link's frame, the status, the
robot's model (see :mod:`.sources` for the topics). The link frames are those of the arm's
URDF (:mod:`robocli.robots.urdf`): ``NAME/link_i`` turns with joint ``i``, at its axis."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from robocli.errors import InvalidArgument
from robocli.io import schemas as S
from robocli.io.record.links import RawLink, Sink, TopicDecoder, json_text
from robocli.io.record.models import add_model
from robocli.robots.urdf import arm_transforms, arm_urdf, joint_origins

if TYPE_CHECKING:
    from robocli.devices.arm import Arm

__all__ = ["ArmDecoder", "attach_arm"]


def arm_links(rec: Sink, name: str = "arm", *, byte_order: str = "little", real_size: int = 4,
              ports: str = "both") -> tuple[str, dict[str, RawLink]]:  # fmt: skip
    """Raw links for an arm not connected yet: ``(name, {port: link})``, to hand to
    ``Arm.connect(listeners=...)`` (a mapping by port, as it takes) so that every frame of
    each port is recorded from its first byte; a later ``add(arm, name)`` decodes on top of
    them. ``name``: ``arm`` (numbered when taken)."""
    if ports not in ("both", "motion", "state"):
        raise InvalidArgument(f"ports must be 'motion', 'state' or 'both', not {ports!r}")
    name = rec.unique_name(name)
    protocol = "sm-be" if byte_order == "big" else "sm-le"
    links = {}
    for port in ("motion", "state"):
        if ports in ("both", port):
            link = RawLink(rec, name, protocol, port=port, byte_order=byte_order,
                           real_size=str(real_size))  # fmt: skip
            rec.links[f"{name}/{port}"] = links[port] = link
    return name, links


def attach_arm(rec: Sink, arm: Arm, name: str, ports: str = "both") -> str:
    """``name``: the default ``arm`` (numbered), or the name :func:`arm_links` gave the links
    handed to ``Arm.connect``; ``ports``: which ports to record (from now on)."""
    if ports not in ("both", "motion", "state"):
        raise InvalidArgument(f"ports must be 'motion', 'state' or 'both', not {ports!r}")
    made = {port: rec.links[f"{name}/{port}"] for port in ("motion", "state")
            if f"{name}/{port}" in rec.links}  # fmt: skip
    if any(link.decoder is not None for link in made.values()):
        raise InvalidArgument(f"{name!r} is recorded already")
    if not made:
        name, made = arm_links(rec, name, byte_order="big" if arm.byteorder == ">" else "little",
                               real_size=arm.real, ports=ports)  # fmt: skip
        for port, link in list(made.items()):
            if port not in arm.stats:  # a port this Arm did not open
                del made[port]
                continue
            arm.add_listener(link, ports=port)
            rec.on_close(_detach_arm(arm, link, port))
    add_model(rec, name, arm_urdf(arm.robot, f"{name}/"))
    decoder = ArmDecoder(rec, name, arm)
    for port, link in made.items():
        link.decoder = decoder if port == "state" else _no_decoding
    return name


def _no_decoding(direction: str, payload: bytes, ns: int) -> None:
    """The motion port's frames: in its raw channels, nothing more to decode."""


def _detach_arm(arm: Arm, link: RawLink, port: str) -> Callable[[], None]:
    return lambda: arm.remove_listener(link, ports=port)


class ArmDecoder(TopicDecoder):
    """State-port frames (writer thread) -> joint states, flange pose, link frames, status.

    The controller's clock (JOINT_FEEDBACK's time) is put on the host clock by the smallest
    receive-minus-controller time seen so far (the transport delay's floor is taken as 0)."""

    def __init__(self, rec: Sink, name: str, arm: Arm) -> None:
        super().__init__(rec, name, ("joint_states", "joint_feedback", "tcp", "tf", "status"))
        self.model = arm.robot
        self.order, self.real = arm.byteorder, arm.real
        n = self.model.n_joints
        self.names = [f"joint_{i + 1}" for i in range(n)]
        self.frames = [f"{name}/base", *(f"{name}/link_{i + 1}" for i in range(n))]
        self.offset: float | None = None  #: host epoch s minus controller s (min so far)
        self._feedback = False  # JOINT_FEEDBACK seen: the frames follow it
        self._flange = joint_origins(self.model)[-1]

    def __call__(self, direction: str, frame: bytes, ns: int) -> None:
        from robocli.protocols import simple_message as sm
        from robocli.protocols.simple_message import SimpleMessageType, ValidFields

        if direction != "rx":
            return
        msg = sm.decode(frame, byteorder=self.order, real=self.real)
        body = msg.body
        if not isinstance(body, dict):
            return
        n = self.model.n_joints
        if msg.msg_type == SimpleMessageType.JOINT_POSITION:
            self._joints("joint_states", ns, ns, list(body["joints"][:n]), [], None)
        elif (
            msg.msg_type == SimpleMessageType.JOINT_FEEDBACK
            and body["valid_fields"] & ValidFields.POSITION
        ):
            valid = body["valid_fields"]
            rt = float(body["time"]) if valid & ValidFields.TIME else None
            publish = ns
            if rt is not None:
                seen = ns / 1e9 - rt
                self.offset = seen if self.offset is None else min(self.offset, seen)
                publish = min(ns, int((rt + self.offset) * 1e9))  # (float rounding)
            vel = list(body["velocities"][:n]) if valid & ValidFields.VELOCITY else []
            self._feedback = True
            self._joints("joint_feedback", ns, publish, list(body["positions"][:n]), vel, rt)
        elif msg.msg_type == SimpleMessageType.STATUS:
            from robocli.devices.arm.state import ArmStatus

            status = ArmStatus.from_body(body, 0.0).as_dict()
            status = {k: v for k, v in status.items() if v is not None}  # unknown: left out
            status["timestamp"] = S.stamp(ns)
            cid = self._cid("status", "robocli.arm.Status")
            self.rec.write(cid, json_text(status).encode(), ns)

    def _joints(self, topic: str, ns: int, publish: int, q: list[float], vel: list[float],
                robot_time: float | None) -> None:  # fmt: skip
        rec = self.rec
        stamp = S.stamp(publish)
        source = "joint_feedback" if topic == "joint_feedback" else "joint_position"
        state: dict[str, Any] = {"timestamp": stamp, "name": self.names, "position": q,
                                 "velocity": vel, "effort": [], "source": source}  # fmt: skip
        if robot_time is not None:  # not sent: left out (a viewer's schemas have no null)
            state["robot_time"] = robot_time
        rec.write(self._cid(topic, "robocli.JointState"), json_text(state).encode(), ns, publish)
        if self._feedback and topic != "joint_feedback":
            return  # the frames follow the feedback, on the controller's clock
        if len(q) != self.model.n_joints:
            return  # a controller with fewer joints than the model: no frames to give
        transforms = []
        chain = np.eye(4)
        for i, m in enumerate(arm_transforms(self.model, q)):  # the URDF's joints, moved
            t = (float(m[0, 3]), float(m[1, 3]), float(m[2, 3]))
            transforms.append(S.frame_transform(publish, self.frames[i], self.frames[i + 1], t,
                                                _quaternion(m)))  # fmt: skip
            chain = chain @ m
        chain = chain @ self._flange
        rot, pos = chain[:3, :3], chain[:3, 3]
        rec.write(self._cid("tf", "foxglove.FrameTransforms"),
                  json_text({"transforms": transforms}).encode(), ns, publish)  # fmt: skip
        x, y, z = (float(v) for v in pos)
        tcp = {"timestamp": stamp, "frame_id": self.frames[0],
               "pose": S.pose(x, y, z, _quaternion(rot))}  # fmt: skip
        rec.write(self._cid("tcp", "foxglove.PoseInFrame"), json_text(tcp).encode(), ns, publish)


def _quaternion(r: Any) -> dict[str, float]:
    """The unit quaternion of a 3 x 3 rotation matrix (Shepperd's method)."""
    m00, m11, m22 = float(r[0, 0]), float(r[1, 1]), float(r[2, 2])
    trace = m00 + m11 + m22
    if trace > 0:
        s = 2.0 * math.sqrt(trace + 1.0)
        w, x = 0.25 * s, (float(r[2, 1]) - float(r[1, 2])) / s
        y, z = (float(r[0, 2]) - float(r[2, 0])) / s, (float(r[1, 0]) - float(r[0, 1])) / s
    elif m00 > m11 and m00 > m22:
        s = 2.0 * math.sqrt(1.0 + m00 - m11 - m22)
        w, x = (float(r[2, 1]) - float(r[1, 2])) / s, 0.25 * s
        y, z = (float(r[0, 1]) + float(r[1, 0])) / s, (float(r[0, 2]) + float(r[2, 0])) / s
    elif m11 > m22:
        s = 2.0 * math.sqrt(1.0 + m11 - m00 - m22)
        w, x = (float(r[0, 2]) - float(r[2, 0])) / s, (float(r[0, 1]) + float(r[1, 0])) / s
        y, z = 0.25 * s, (float(r[1, 2]) + float(r[2, 1])) / s
    else:
        s = 2.0 * math.sqrt(1.0 + m22 - m00 - m11)
        w, x = (float(r[1, 0]) - float(r[0, 1])) / s, (float(r[0, 2]) + float(r[2, 0])) / s
        y, z = (float(r[1, 2]) + float(r[2, 1])) / s, 0.25 * s
    return {"x": x, "y": y, "z": z, "w": w}
