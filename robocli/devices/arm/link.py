"""The bytes of the Arm's links: sessions on the motion and state ports and the first reads
on them (a refusal, another protocol), JOINT_TRAJ_PT frames, packet names for the
statistics."""

from __future__ import annotations

import struct
from collections.abc import Callable

from robocli.core import Framer
from robocli.devices.arm.state import Point
from robocli.devices.session import Session
from robocli.errors import (
    ConnectionLost,
    DeviceError,
    InvalidArgument,
    RobocliError,
    TimeoutError,
    TransportError,
)
from robocli.kinematics.model import RobotModel
from robocli.protocols import simple_message as sm
from robocli.protocols.common import find_refusal
from robocli.protocols.simple_message import CommType, SimpleMessageType, SpecialSeq
from robocli.transports import SocketTransport

__all__ = [
    "first_state", "namer", "need", "no_refusal", "open_session", "point_frame", "stop_frame",
]  # fmt: skip


def open_session(
    host: str,
    port: int,
    name: str,
    order: sm.ByteOrder,
    real: sm.RealSize,
    timeout: float,
    stop: list[bytes],
) -> Session:
    """One port's session (not started); its emergency stop is ``stop``."""
    try:
        transport = SocketTransport.connect(host, port, timeout)
    except TransportError as exc:
        if "connection refused" not in str(exc):
            raise
        raise TransportError(
            f"cannot connect to tcp://{host}:{port}: connection refused (is "
            f"the controller's {name} server, or `robocli sim abb`, "
            "listening there?)"
        ) from None
    framer = Framer("sm-le" if order == "<" else "sm-be", sm.MAX_FRAME_SIZE)
    return Session(transport, framer, on_frame=lambda f, t: None, name_of=namer(order, real),
                   emergency_stop=lambda: stop, name=f"arm-{name}")  # fmt: skip


def point_frame(seq: int, p: Point, order: sm.ByteOrder, real: sm.RealSize) -> bytes:
    """One JOINT_TRAJ_PT SERVICE_REQUEST (joints padded to 10 with zeros)."""
    body = {"sequence": int(seq), "joints": list(p.joints), "velocity": p.velocity,
            "duration": p.duration}  # fmt: skip
    return sm.encode(SimpleMessageType.JOINT_TRAJ_PT, CommType.SERVICE_REQUEST, 0, body,
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
            return SimpleMessageType(msg_type).name
        except ValueError:
            return f"TYPE_{msg_type}"

    return name_of


def first_state(s: Session, timeout: float) -> None:
    """Read until the first valid state message (before the reader starts, so that a
    refusal line or another protocol is seen)."""
    url = s.transport.url
    wrong = TransportError(
        f"{url}: the port answers, but not in Simple Message "
        "(another protocol, or the wrong byte order or real size)"
    )
    try:
        s.request(None, lambda f: True, timeout)
        # a stream in the other byte order frames 3 bytes late (small ints even decode)
        if s.stats.dropped_bytes or s.stats.decode_errors:
            raise wrong
    except ConnectionLost:
        reason = find_refusal(s.raw_tail())
        if reason is not None:
            raise DeviceError(f"{url}: {reason}") from None
        raise
    except TimeoutError:
        if s.raw_tail() or s.stats.decode_errors:
            raise wrong from None
        raise TimeoutError(f"{url}: no state message within {timeout:g} s") from None


def no_refusal(s: Session, wait: float) -> None:
    """Raise :class:`DeviceError` when the motion port refused this client (a busy
    server says why on connecting, then closes): its motion port is quiet otherwise, so
    read what came within ``wait`` s before the reader starts (and would swallow it)."""
    try:
        s.request(None, lambda f: False, wait)
    except TimeoutError:
        return  # nothing said: a controller's motion port speaks only when spoken to
    except RobocliError:
        reason = find_refusal(s.raw_tail())
        if reason is not None:
            raise DeviceError(f"{s.transport.url}: {reason}") from None
        raise


def need(session: Session | None, name: str) -> Session:
    """``session``, checked alive: the port an operation needs."""
    if session is None:
        raise InvalidArgument(f"this Arm was connected without its {name} port")
    session.check()
    return session
