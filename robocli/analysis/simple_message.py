"""Simple Message frames named and decoded (``robocli dump arm``): by type and reply code,
joints cut to the arm's, trajectory sequence numbers with a meaning of their own named."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from robocli.analysis.packets import Packet
from robocli.errors import FramingError, ProtocolError

if TYPE_CHECKING:
    from robocli.protocols import simple_message as sm

__all__ = ["SimpleMessageDecoder", "describe_message"]

#: Simple Message trajectory sequence numbers with a meaning of their own.
_SEQ = {-1: "start", -2: "stream", -3: "end", -4: "STOP"}
_VALID_BITS = {"time": 1, "positions": 2, "velocities": 4, "accelerations": 8}


def describe_message(frame: bytes, order: sm.ByteOrder = "<", real: sm.RealSize = 4,
                     n_joints: int = 6) -> tuple[str, dict[str, Any]]:  # fmt: skip
    """Name and decoded fields of one whole Simple Message frame (joints cut to
    ``n_joints``). A frame that does not decode is named ``undecodable`` with the reason."""
    from robocli.protocols import simple_message as sm
    from robocli.protocols.simple_message import CommType, ReplyCode, SimpleMessageType

    try:
        msg = sm.decode(frame, byteorder=order, real=real)
    except (FramingError, ProtocolError) as exc:
        return "undecodable", {"error": str(exc)}
    name = (
        msg.msg_type.name if isinstance(msg.msg_type, SimpleMessageType) else f"TYPE_{msg.msg_type}"
    )
    if msg.comm_type == CommType.SERVICE_REQUEST:
        name += " req"
    elif msg.comm_type == CommType.SERVICE_REPLY:
        code = msg.reply_code
        name += " " + (code.name if isinstance(code, ReplyCode) else f"reply {code}")
    body = msg.body
    if not isinstance(body, dict):
        return name, ({"bytes": len(body)} if isinstance(body, bytes) and body else {})
    valid = body.get("valid_fields")
    fields: dict[str, Any] = {}
    for key, value in body.items():
        if valid is not None and key in _VALID_BITS and not valid & _VALID_BITS[key]:
            continue  # JOINT_FEEDBACK / JOINT_TRAJ_PT_FULL: only the fields it says are valid
        if isinstance(value, list):
            value = value[:n_joints]
        if key == "sequence" and value in _SEQ:
            value = f"{value}({_SEQ[value]})"
        fields[key] = value
    return name, fields


class SimpleMessageDecoder:
    """Names and decodes whole frames of ``order`` and ``real`` size (joints cut to
    ``n_joints``); called as ``decoder(direction, frame, t)`` where ``direction`` may carry
    the port (``"tx:motion"``)."""

    def __init__(self, order: sm.ByteOrder = "<", real: sm.RealSize = 4,
                 n_joints: int = 6) -> None:  # fmt: skip
        self.order, self.real, self.n_joints = order, real, n_joints

    def __call__(self, direction: str, frame: bytes, t: float | None) -> Packet:
        way, _, port = direction.partition(":")
        name, fields = describe_message(frame, self.order, self.real, self.n_joints)
        return Packet(t, way, name, fields, frame, port=port or None)
