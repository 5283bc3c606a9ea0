"""Simple Message declared once with ``construct``: :class:`SimpleMessageSpec`, the
declarations for one byte order and real size, built once and cached by :func:`messages`.

Part of :mod:`robocli.protocols.simple_message` (import from there).
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import construct as cs

from robocli.errors import ProtocolError
from robocli.protocols.simple_message.constants import HEADER_SIZE, MAX_JOINTS, SimpleMessageType

ByteOrder = Literal["<", ">"]
RealSize = Literal[4, 8]


class _FixedArray(cs.Adapter):  # type: ignore[misc]  # construct has no type hints
    """``count`` elements on the wire; a shorter list is padded with zeros when building."""

    def __init__(self, count: int, subcon: Any, fill: float | int) -> None:
        super().__init__(cs.Array(count, subcon))
        self.count = count
        self.fill = fill

    def _decode(self, obj: Any, context: Any, path: Any) -> list[Any]:
        return list(obj)

    def _encode(self, obj: Any, context: Any, path: Any) -> list[Any]:
        values = list(obj)
        if len(values) > self.count:
            raise cs.RangeError(
                f"at most {self.count} elements allowed, got {len(values)}", path=path
            )
        return values + [self.fill] * (self.count - len(values))


@dataclass(frozen=True)
class SimpleMessageSpec:
    """The ``construct`` declarations of Simple Message for one byte order and real size.

    Body field names (used by :func:`encode`/:func:`decode` dicts):

    * PING (REP-I0006 40-byte body): ``data`` (10 int32). The library sends PING header-only.
    * GET_VERSION reply: ``major``, ``minor``, ``patch``.
    * JOINT_POSITION: ``sequence``, ``joints``.
    * JOINT_TRAJ_PT: ``sequence``, ``joints``, ``velocity`` (fraction of max), ``duration`` (s).
    * JOINT_TRAJ (library layout): ``points`` (JOINT_TRAJ_PT dicts), ``size`` (defaults to the
      number of points).
    * STATUS: ``drives_powered``, ``e_stopped``, ``error_code``, ``in_error``, ``in_motion``,
      ``mode``, ``motion_possible``.
    * JOINT_TRAJ_PT_FULL: ``robot_id``, ``sequence``, ``valid_fields``, ``time``,
      ``positions``, ``velocities``, ``accelerations``.
    * JOINT_FEEDBACK: as JOINT_TRAJ_PT_FULL without ``sequence``.
    * MOTOMAN_MOTION_CTRL: ``robot_id``, ``sequence``, ``command``, ``data``.
    * MOTOMAN_MOTION_REPLY: ``robot_id``, ``sequence``, ``command``, ``result``, ``subcode``,
      ``data``.

    Arrays are built from lists of up to :data:`MAX_JOINTS` values (padded with zeros) and
    always decode to :data:`MAX_JOINTS` values. Arrays whose ``valid_fields`` bit is clear
    are kept as they are on the wire (the reference library does not zero them).
    """

    byteorder: ByteOrder
    real: RealSize
    Int: Any
    Real: Any
    Prefix: Any
    Header: Any
    Ping: Any
    GetVersionReply: Any
    JointPosition: Any
    JointTrajPt: Any
    JointTraj: Any
    JointTrajRep: Any
    Status: Any
    JointTrajPtFull: Any
    JointFeedback: Any
    MotomanMotionCtrl: Any
    MotomanMotionReply: Any
    Frame: Any
    bodies: Mapping[int, Any]
    """msg_type -> fixed-size body declaration (PING: its REP-I0006 40-byte body)."""

    def body_size(self, msg_type: int, body: Mapping[str, Any] | bytes | None) -> int:
        """Bytes the given body takes on the wire for ``msg_type``."""
        if body is None:
            return 0
        if isinstance(body, (bytes, bytearray, memoryview)):
            return len(body)
        if msg_type == SimpleMessageType.JOINT_TRAJ:
            return int(self.JointTrajPt.sizeof()) * len(body["points"]) + 4
        decl = self.bodies.get(msg_type)
        if decl is None:
            raise ProtocolError(
                f"no body declaration for msg_type {msg_type}: pass the body as bytes"
            )
        return int(decl.sizeof())


def _build_spec(byteorder: ByteOrder, real: RealSize) -> SimpleMessageSpec:
    if byteorder not in ("<", ">"):
        raise ValueError(f"byteorder must be '<' or '>', not {byteorder!r}")
    if real not in (4, 8):
        raise ValueError(f"real must be 4 or 8, not {real!r}")
    big = byteorder == ">"
    Int = cs.Int32sb if big else cs.Int32sl
    if real == 4:
        Real = cs.Float32b if big else cs.Float32l
    else:
        Real = cs.Float64b if big else cs.Float64l

    def joints() -> Any:
        return _FixedArray(MAX_JOINTS, Real, 0.0)

    Prefix = cs.Struct("length" / Int)
    Header = cs.Struct("msg_type" / Int, "comm_type" / Int, "reply_code" / Int)
    Ping = cs.Struct("data" / _FixedArray(MAX_JOINTS, Int, 0))
    GetVersionReply = cs.Struct("major" / Int, "minor" / Int, "patch" / Int)
    JointPosition = cs.Struct("sequence" / Int, "joints" / joints())
    JointTrajPt = cs.Struct(
        "sequence" / Int, "joints" / joints(), "velocity" / Real, "duration" / Real
    )
    JointTraj = cs.Struct(
        # GreedyRange stops (and rewinds) when the 4 trailing bytes cannot form a point.
        "points" / cs.GreedyRange(JointTrajPt),
        "size" / cs.Default(Int, lambda this: len(this.points)),
    )
    JointTrajRep = cs.Struct("size" / Int, "points" / cs.Array(MAX_JOINTS, JointTrajPt))
    Status = cs.Struct(
        "drives_powered" / Int,
        "e_stopped" / Int,
        "error_code" / Int,
        "in_error" / Int,
        "in_motion" / Int,
        "mode" / Int,
        "motion_possible" / Int,
    )
    JointTrajPtFull = cs.Struct(
        "robot_id" / Int,
        "sequence" / Int,
        "valid_fields" / Int,
        "time" / Real,
        "positions" / joints(),
        "velocities" / joints(),
        "accelerations" / joints(),
    )
    JointFeedback = cs.Struct(
        "robot_id" / Int,
        "valid_fields" / Int,
        "time" / Real,
        "positions" / joints(),
        "velocities" / joints(),
        "accelerations" / joints(),
    )
    MotomanMotionCtrl = cs.Struct(
        "robot_id" / Int, "sequence" / Int, "command" / Int, "data" / joints()
    )
    MotomanMotionReply = cs.Struct(
        "robot_id" / Int,
        "sequence" / Int,
        "command" / Int,
        "result" / Int,
        "subcode" / Int,
        "data" / joints(),
    )
    bodies: dict[int, Any] = {
        SimpleMessageType.PING: Ping,
        SimpleMessageType.GET_VERSION: GetVersionReply,
        SimpleMessageType.JOINT_POSITION: JointPosition,
        SimpleMessageType.JOINT_TRAJ_PT: JointTrajPt,
        SimpleMessageType.STATUS: Status,
        SimpleMessageType.JOINT_TRAJ_PT_FULL: JointTrajPtFull,
        SimpleMessageType.JOINT_FEEDBACK: JointFeedback,
        SimpleMessageType.MOTOMAN_MOTION_CTRL: MotomanMotionCtrl,
        SimpleMessageType.MOTOMAN_MOTION_REPLY: MotomanMotionReply,
    }
    sizes = {int(k): int(v.sizeof()) for k, v in bodies.items()}
    point_size = int(JointTrajPt.sizeof())

    def body_key(this: Any) -> Any:
        n = this.length - HEADER_SIZE
        msg_type = this.header["msg_type"]
        if n == 0:
            return "empty"
        if isinstance(this.get("body"), bytes):  # building from raw bytes
            return "raw"
        if sizes.get(msg_type) == n:
            return int(msg_type)
        if msg_type == SimpleMessageType.JOINT_TRAJ and n > 4 and (n - 4) % point_size == 0:
            return int(msg_type)
        return "raw"

    cases: dict[Any, Any] = {int(k): v for k, v in bodies.items()}
    cases[int(SimpleMessageType.JOINT_TRAJ)] = JointTraj
    cases["empty"] = cs.Pass

    spec: SimpleMessageSpec

    def frame_length(this: Any) -> int:
        return HEADER_SIZE + spec.body_size(this.header["msg_type"], this.body)

    Frame = cs.Struct(
        "length" / cs.Rebuild(Int, frame_length),
        "header" / Header,
        "body"
        / cs.FixedSized(
            cs.this.length - HEADER_SIZE, cs.Switch(body_key, cases, default=cs.GreedyBytes)
        ),
    )
    spec = SimpleMessageSpec(
        byteorder=byteorder,
        real=real,
        Int=Int,
        Real=Real,
        Prefix=Prefix,
        Header=Header,
        Ping=Ping,
        GetVersionReply=GetVersionReply,
        JointPosition=JointPosition,
        JointTrajPt=JointTrajPt,
        JointTraj=JointTraj,
        JointTrajRep=JointTrajRep,
        Status=Status,
        JointTrajPtFull=JointTrajPtFull,
        JointFeedback=JointFeedback,
        MotomanMotionCtrl=MotomanMotionCtrl,
        MotomanMotionReply=MotomanMotionReply,
        Frame=Frame,
        bodies=bodies,
    )
    return spec


def messages(byteorder: ByteOrder = "<", real: RealSize = 4) -> SimpleMessageSpec:
    """The declarations for one byte order (``"<"``/``">"``) and real size (4/8 bytes).

    The reference library exists as ``"<"``/4 (plain), ``">"``/4 (``_bswap``) and ``"<"``/8
    (``FLOAT64``); ``">"``/8 is accepted too although no reference peer speaks it.
    Cached: the same object is returned for the same arguments.
    """
    return _cached_spec(byteorder, real)


_cached_spec = functools.lru_cache(maxsize=None)(_build_spec)
