"""ROS-Industrial Simple Message, declared once with ``construct``.

Facts from ``shared/protocols/simple_message.md`` (REP-I0004, REP-I0006, industrial_core,
abb_driver, motoman_driver) and the frames recorded from the reference C++ library
(``tests/data/simple_message/``). Reimplemented from those facts; no reference code is used.

Wire format (no sync bytes, no checksum, segmentation by byte counting)::

    int32 length | int32 msg_type | int32 comm_type | int32 reply_code | body
    <- prefix -> <----------------- header (12 B) ----------------> <- length - 12 ->

The byte order is not fixed by the protocol: ``"<"`` (ABB, DX100/DX200/YRC1000 MotoROS, the
plain library on x86) or ``">"`` (Fanuc, FS100, the library's ``_bswap`` flavour; every field
is swapped on its own, the length prefix included). Reals are float32, or float64 for the
library's ``FLOAT64`` flavour (ints stay int32). :func:`messages` returns the declarations for
one combination.

Bodies decoded by :data:`SimpleMessageSpec.Frame` are chosen by ``msg_type`` *and* body
length: a header-only frame has body ``None``; a body of the standard size is parsed into a
dict; any other size is kept as raw ``bytes``. Unlike the reference library, which parses
bodies from the end (``ByteArray::unload`` is LIFO, so extra *leading* bytes are silently
ignored), a body of a non-standard size is never guessed at.

JOINT_TRAJ (12) uses the **library layout** (``JointTraj::load``): the points first, the
``int32 size`` last. REP-I0006 puts ``size`` first; :attr:`SimpleMessageSpec.JointTrajRep`
declares that layout, but :attr:`SimpleMessageSpec.Frame` decodes the library layout only.

Values are raw protocol values (radians, metres, seconds are already the protocol's units).
"""

from __future__ import annotations

import enum
import functools
import struct
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

import construct as cs

from robocli.errors import FramingError, ProtocolError
from robocli.protocols.common import DECODE_ERRORS, enum_name, enum_or_int, plain, undecodable

ByteOrder = Literal["<", ">"]
RealSize = Literal[4, 8]

# ------------------------------------------------------------------------------ constants

PORT_MOTION = 11000
"""Trajectory relay (ABB motion server, Fanuc ``ros_relay``, generic downloader/streamer)."""
PORT_SYSTEM = 11001
"""Defined by industrial_core, unused."""
PORT_STATE = 11002
"""State relay (JOINT_POSITION + STATUS from ABB, Fanuc ``ros_state``)."""
PORT_IO = 11003
"""Defined by industrial_core, unused."""
MOTOMAN_PORT_MOTION = 50240
MOTOMAN_PORT_STATE = 50241
MOTOMAN_PORT_IO = 50242

MAX_JOINTS = 10
"""Every joint array has exactly this many elements on the wire (unused ones zero)."""
PREFIX_SIZE = 4
HEADER_SIZE = 12
MIN_LENGTH = HEADER_SIZE
"""Smallest valid ``length`` prefix (a header-only frame)."""
MAX_FRAME_SIZE = 1023
"""Largest whole frame a C++ peer sends (``SimpleSocket`` refuses buffers of 1024 bytes)."""
MAX_LENGTH = MAX_FRAME_SIZE - PREFIX_SIZE
"""Largest ``length`` prefix accepted by :func:`decode` and produced by :func:`encode`."""
UDP_HANDSHAKE = 0x8E
"""Byte exchanged until echoed before framing starts on the (rarely used) UDP variant."""


class MsgType(enum.IntEnum):
    """Standard message ids (REP-I0004) plus the Motoman ones robocli declares."""

    INVALID = 0
    PING = 1
    GET_VERSION = 2
    JOINT_POSITION = 10
    JOINT = 10  # alias used by industrial_core
    JOINT_TRAJ_PT = 11
    JOINT_TRAJ = 12
    STATUS = 13
    JOINT_TRAJ_PT_FULL = 14
    JOINT_FEEDBACK = 15
    READ_INPUT = 20
    WRITE_OUTPUT = 21
    MOTOMAN_MOTION_CTRL = 2001
    MOTOMAN_MOTION_REPLY = 2002


class CommType(enum.IntEnum):
    INVALID = 0
    TOPIC = 1
    SERVICE_REQUEST = 2
    SERVICE_REPLY = 3


class ReplyCode(enum.IntEnum):
    INVALID = 0
    UNUSED = 0
    SUCCESS = 1
    FAILURE = 2


class SpecialSeq(enum.IntEnum):
    """Special ``sequence`` values of JOINT_TRAJ_PT (N >= 0 is a point index)."""

    START_TRAJECTORY_DOWNLOAD = -1
    START_TRAJECTORY_STREAMING = -2
    END_TRAJECTORY = -3
    STOP_TRAJECTORY = -4


class TriState(enum.IntEnum):
    UNKNOWN = -1
    FALSE = 0
    OFF = 0
    DISABLED = 0
    LOW = 0
    TRUE = 1
    ON = 1
    ENABLED = 1
    HIGH = 1


class RobotMode(enum.IntEnum):
    UNKNOWN = -1
    MANUAL = 1
    AUTO = 2


class ValidFields(enum.IntFlag):
    """``valid_fields`` bits of JOINT_TRAJ_PT_FULL / JOINT_FEEDBACK."""

    TIME = 0x01
    POSITION = 0x02
    VELOCITY = 0x04
    ACCELERATION = 0x08


class MotomanCommand(enum.IntEnum):
    """``command`` of MOTOMAN_MOTION_CTRL (2001)."""

    CHECK_MOTION_READY = 200101
    CHECK_QUEUE_CNT = 200102
    STOP_MOTION = 200111
    START_SERVOS = 200112
    STOP_SERVOS = 200113
    RESET_ALARM = 200114
    START_TRAJ_MODE = 200121
    STOP_TRAJ_MODE = 200122
    DISCONNECT = 200130


class MotomanResult(enum.IntEnum):
    """``result`` of MOTOMAN_MOTION_REPLY (2002)."""

    SUCCESS = 0
    TRUE = 0
    BUSY = 1
    FAILURE = 2
    FALSE = 2
    INVALID = 3
    ALARM = 4
    NOT_READY = 5
    MP_FAILURE = 6


# ------------------------------------------------------------------------------ declarations


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
        if msg_type == MsgType.JOINT_TRAJ:
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
        MsgType.PING: Ping,
        MsgType.GET_VERSION: GetVersionReply,
        MsgType.JOINT_POSITION: JointPosition,
        MsgType.JOINT_TRAJ_PT: JointTrajPt,
        MsgType.STATUS: Status,
        MsgType.JOINT_TRAJ_PT_FULL: JointTrajPtFull,
        MsgType.JOINT_FEEDBACK: JointFeedback,
        MsgType.MOTOMAN_MOTION_CTRL: MotomanMotionCtrl,
        MsgType.MOTOMAN_MOTION_REPLY: MotomanMotionReply,
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
        if msg_type == MsgType.JOINT_TRAJ and n > 4 and (n - 4) % point_size == 0:
            return int(msg_type)
        return "raw"

    cases: dict[Any, Any] = {int(k): v for k, v in bodies.items()}
    cases[int(MsgType.JOINT_TRAJ)] = JointTraj
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


# ------------------------------------------------------------------------------ helpers


@dataclass(frozen=True)
class Message:
    """One decoded frame. ``body``: ``None`` (header only), a dict, or raw ``bytes``."""

    msg_type: int
    comm_type: int
    reply_code: int
    body: dict[str, Any] | bytes | None = None


def validate_header(msg_type: int, comm_type: int, reply_code: int) -> None:
    """Apply the reference library's header rule, or raise :class:`ProtocolError`.

    ``msg_type != 0``, ``comm_type != 0``, and ``reply_code != 0`` exactly when
    ``comm_type == SERVICE_REPLY``. Nothing else is checked (undefined types, comm types and
    reply codes are legal), exactly like ``SimpleMessage::validateMessage``.
    """
    if msg_type == 0:
        raise ProtocolError("invalid Simple Message header: msg_type is 0 (INVALID)")
    if comm_type == 0:
        raise ProtocolError(
            f"invalid Simple Message header: comm_type is 0 (INVALID), msg_type {msg_type}"
        )
    if comm_type == CommType.SERVICE_REPLY:
        if reply_code == 0:
            raise ProtocolError(
                f"invalid Simple Message header: SERVICE_REPLY with reply_code 0, "
                f"msg_type {msg_type}"
            )
    elif reply_code != 0:
        raise ProtocolError(
            f"invalid Simple Message header: reply_code {reply_code} on comm_type "
            f"{comm_type} (only SERVICE_REPLY may carry one), msg_type {msg_type}"
        )


def encode(
    msg_type: int,
    comm_type: int,
    reply_code: int = 0,
    body: Mapping[str, Any] | bytes | None = None,
    *,
    byteorder: ByteOrder = "<",
    real: RealSize = 4,
) -> bytes:
    """One whole frame (prefix included).

    ``body`` is ``None`` (header only), a dict of the fields of ``msg_type``'s body, or raw
    ``bytes``. Raises :class:`ProtocolError` for a header the reference library would refuse
    to send, an unknown body, or a frame longer than :data:`MAX_FRAME_SIZE`.
    """
    validate_header(msg_type, comm_type, reply_code)
    spec = messages(byteorder, real)
    if isinstance(body, (bytearray, memoryview)):
        body = bytes(body)
    try:
        size = PREFIX_SIZE + HEADER_SIZE + spec.body_size(msg_type, body)
    except (KeyError, TypeError) as exc:
        raise ProtocolError(f"cannot encode Simple Message {msg_type}: {exc!r}") from exc
    if size > MAX_FRAME_SIZE:
        raise ProtocolError(
            f"Simple Message frame of {size} bytes exceeds the {MAX_FRAME_SIZE}-byte limit"
        )
    header = {"msg_type": msg_type, "comm_type": comm_type, "reply_code": reply_code}
    try:
        data: bytes = spec.Frame.build({"header": header, "body": body})
    except (cs.ConstructError, KeyError, TypeError, ValueError) as exc:
        raise ProtocolError(f"cannot encode Simple Message {msg_type}: {exc!r}") from exc
    return data


def decode(
    frame: bytes,
    *,
    byteorder: ByteOrder = "<",
    real: RealSize = 4,
    validate: bool = True,
    max_length: int = MAX_LENGTH,
) -> Message:
    """Decode one whole frame (prefix included).

    Raises :class:`FramingError` when the prefix does not match the frame (``length`` < 12,
    > ``max_length``, or not equal to ``len(frame) - 4``) and, with ``validate``,
    :class:`ProtocolError` for a header the reference library rejects.
    """
    frame = bytes(frame)
    if len(frame) < PREFIX_SIZE + HEADER_SIZE:
        raise FramingError(
            f"Simple Message frame of {len(frame)} bytes is shorter than prefix + header (16)"
        )
    (length,) = struct.unpack(byteorder + "i", frame[:PREFIX_SIZE])
    if length < MIN_LENGTH or length > max_length:
        raise FramingError(
            f"Simple Message length prefix {length} outside {MIN_LENGTH}..{max_length}"
        )
    if length != len(frame) - PREFIX_SIZE:
        raise FramingError(
            f"Simple Message length prefix {length} does not match the "
            f"{len(frame) - PREFIX_SIZE} bytes after it"
        )
    spec = messages(byteorder, real)
    try:
        parsed = spec.Frame.parse(frame)
    except DECODE_ERRORS as exc:
        (msg_type,) = struct.unpack_from(byteorder + "i", frame, PREFIX_SIZE)
        undecodable(f"Simple Message {enum_name(MsgType, msg_type, str(msg_type))}", frame, exc)
    header = parsed.header
    if validate:
        validate_header(header.msg_type, header.comm_type, header.reply_code)
    body = parsed.body
    return Message(
        msg_type=enum_or_int(MsgType, header.msg_type),
        comm_type=enum_or_int(CommType, header.comm_type),
        reply_code=enum_or_int(ReplyCode, header.reply_code),
        body=body if body is None or isinstance(body, bytes) else plain(body),
    )


__all__ = [
    "HEADER_SIZE",
    "MAX_FRAME_SIZE",
    "MAX_JOINTS",
    "MAX_LENGTH",
    "MIN_LENGTH",
    "MOTOMAN_PORT_IO",
    "MOTOMAN_PORT_MOTION",
    "MOTOMAN_PORT_STATE",
    "PORT_IO",
    "PORT_MOTION",
    "PORT_STATE",
    "PORT_SYSTEM",
    "PREFIX_SIZE",
    "UDP_HANDSHAKE",
    "CommType",
    "Message",
    "MotomanCommand",
    "MotomanResult",
    "MsgType",
    "ReplyCode",
    "RobotMode",
    "SimpleMessageSpec",
    "SpecialSeq",
    "TriState",
    "ValidFields",
    "decode",
    "encode",
    "messages",
    "plain",
    "validate_header",
]
