"""The bytes of the Arm's links: sessions on the motion and state ports, JOINT_TRAJ_PT frames,
packet names for the statistics."""

from __future__ import annotations

import struct
from collections.abc import Callable

from robocli.core import Framer
from robocli.devices.arm.state import Point
from robocli.devices.session import Session
from robocli.errors import TransportError
from robocli.kinematics.model import RobotModel
from robocli.protocols import simple_message as sm
from robocli.protocols.simple_message import CommType, MsgType, SpecialSeq
from robocli.transports import SocketTransport

__all__ = ["namer", "open_session", "point_frame", "stop_frame"]


def open_session(host: str, port: int, name: str, order: sm.ByteOrder, real: sm.RealSize,
                 timeout: float, stop: list[bytes]) -> Session:
    """One port's session (not started); its emergency stop is ``stop``."""
    try:
        transport = SocketTransport.connect(host, port, timeout)
    except TransportError as exc:
        if "connection refused" not in str(exc):
            raise
        raise TransportError(f"cannot connect to tcp://{host}:{port}: connection refused (is "
                             f"the controller's {name} server, or `robocli sim abb`, "
                             "listening there?)") from None
    framer = Framer("sm-le" if order == "<" else "sm-be", sm.MAX_FRAME_SIZE)
    return Session(transport, framer, on_frame=lambda f, t: None, name_of=namer(order, real),
                   emergency_stop=lambda: stop, name=f"arm-{name}")  # fmt: skip


def point_frame(seq: int, p: Point, order: sm.ByteOrder, real: sm.RealSize) -> bytes:
    """One JOINT_TRAJ_PT SERVICE_REQUEST (joints padded to 10 with zeros)."""
    body = {"sequence": int(seq), "joints": list(p.joints), "velocity": p.velocity,
            "duration": p.duration}  # fmt: skip
    return sm.encode(MsgType.JOINT_TRAJ_PT, CommType.SERVICE_REQUEST, 0, body,
                     byteorder=order, real=real)  # fmt: skip


def stop_frame(robot: RobotModel, order: sm.ByteOrder, real: sm.RealSize) -> bytes:
    """STOP (-4) with an all-zero point, as industrial_robot_client sends it."""
    zero = Point((0.0,) * robot.n_joints, 0.0, 0.0)
    return point_frame(SpecialSeq.STOP_TRAJECTORY, zero, order, real)


def namer(order: sm.ByteOrder, real: sm.RealSize) -> Callable[[bytes, str], str]:
    """The session's packet namer: the msg_type's name (``TYPE_<n>`` when unknown)."""
    def name_of(payload: bytes, direction: str) -> str:
        if len(payload) < 8:
            return "short"
        (msg_type,) = struct.unpack_from(order + "i", payload, 4)
        try:
            return MsgType(msg_type).name
        except ValueError:
            return f"TYPE_{msg_type}"

    return name_of
