"""ARCOS: the Pioneer host <-> microcontroller protocol, declared once with ``construct``.

Facts from ``shared/protocols/arcos.md`` (read from AriaCoda, MobileSim, p2os and the
Pioneer 3 manuals). Raw protocol units live only here; devices convert to SI with the
subtype's :class:`RobotParams`.

Framing (both directions, serial and TCP)::

    FA FB  N  type  data...  ck_hi ck_lo      N = 1 + len(data) + 2, checksum over type+data

Client commands carry at most one argument: a sign-magnitude int (``0x3B`` +, ``0x1B`` -, then
an unsigned 16-bit little-endian magnitude), a string (``0x2B``, length byte, bytes), or for
``SIM_SET_POSE`` one ignored type byte then three little-endian int32. Server packets are the
SYNC replies, the standard SIP (0x32/0x33) with optional trailing groups, CONFIG (0x20),
IO (0xF0), encoders (0x90) and battery info (0xFA).
"""

from __future__ import annotations

import enum
import math
import struct
from dataclasses import dataclass, field
from typing import Any

from construct import (
    Adapter,
    Bytes,
    Checksum,
    Const,
    Construct,
    CString,
    FormatField,
    GreedyBytes,
    Int8sl,
    Int8ub,
    Int16sl,
    Int16ub,
    Int16ul,
    Int32sl,
    Int32ul,
    Optional,
    PrefixedArray,
    Rebuild,
    Renamed,
    Select,
    Struct,
    Switch,
    len_,
    this,
)

from robocli.errors import ChecksumError, FramingError, ProtocolError
from robocli.protocols.common import plain

SYNC = b"\xfa\xfb"
MAX_PAYLOAD = 200  #: the simulator keeps every packet's data at most this long (MobileSim rule)
ARG_INT = 0x3B
ARG_NINT = 0x1B
ARG_STR = 0x2B


class Command(enum.IntEnum):
    """Client command numbers (``ArCommands.h``; the manual's command table)."""

    PULSE = 0  # SYNC0 before a session
    OPEN = 1  # SYNC1 before a session
    CLOSE = 2  # SYNC2 before a session
    POLLING = 3
    ENABLE = 4
    SETA = 5
    SETV = 6
    SETO = 7
    MOVE = 8
    ROTATE = 9
    SETRV = 10
    VEL = 11
    HEAD = 12
    DHEAD = 13
    SAY = 15
    JOYREQUEST = 17
    CONFIG = 18
    ENCODER = 19
    SETRVDIR = 20
    RVEL = 21
    DCHEAD = 22
    SETRA = 23
    IMUREQUEST = 26
    SONAR = 28
    STOP = 29
    DIGOUT = 30
    SETPBIOPORT = 31
    VEL2 = 32
    GRIPPER = 33
    ADSEL = 35
    GRIPPERVAL = 36
    GRIPREQUEST = 37
    GYROCALCW = 38
    GYROCALCCW = 39
    IOREQUEST = 40
    PTUPOS = 41
    TTY2 = 42
    GETAUX = 43
    BUMPSTALL = 44
    TCM2 = 45
    JOYDRIVE = 47
    SONARCYCLE = 48
    MOVINGBLINK = 49
    HOSTBAUD = 50
    AUX1BAUD = 51
    AUX2BAUD = 52
    AUX3BAUD = 53
    ESTOP = 55
    ESTALL = 56
    GYRO = 58
    TTY4 = 60
    GETAUX3 = 61
    BATTERYINFO = 62
    CALCOMP = 65
    TTY3 = 66
    GETAUX2 = 67
    CHARGE = 68
    ROTKP = 82
    ROTKV = 83
    ROTKI = 84
    TRANSKP = 85
    TRANSKV = 86
    TRANSKI = 87
    REVCOUNT = 88
    DRIFTFACTOR = 89
    SOUND = 90
    PLAYLIST = 91
    SOUNDTOG = 92
    TICKSMM = 93
    LATVEL = 110
    LATACCEL = 113
    SIM_SET_POSE = 224
    SIM_RESET = 225
    SIM_LRF_ENABLE = 230
    SIM_LRF_FOV_START = 231
    SIM_LRF_FOV_END = 232
    SIM_LRF_RES = 233
    SIM_CTRL = 236
    SIM_STAT = 237
    SIM_MESSAGE = 238
    SIM_EXIT = 239
    BATTEST = 250
    RESET = 253
    MAINTENANCE = 255


class PacketType(enum.IntEnum):
    """Server packet ids (``Aria::getPacketTypeName``)."""

    SYNC0 = 0x00
    SYNC1 = 0x01
    SYNC2 = 0x02
    CONFIG = 0x20
    SIP = 0x32
    SIP_MOVING = 0x33
    SIM_LASER_A = 0x60
    SIM_LASER = 0x61
    SIM_STAT = 0x62
    SIM_INFO = 0x63
    ENCODER = 0x90
    GRIPPER = 0xE0
    IO = 0xF0
    JOYSTICK = 0xF8
    BATTERY = 0xFA
    RESET_NOTICE = 0xFE


#: Commands whose argument is a string (``0x2B`` + length + bytes).
STRING_COMMANDS = frozenset(
    {Command.POLLING, Command.SAY, Command.TTY2, Command.TTY3, Command.TTY4, Command.SIM_MESSAGE}
)
#: Commands whose int argument is two independent bytes (high, low), e.g. VEL2 = (left, right).
TWO_BYTE_COMMANDS = frozenset({Command.DIGOUT, Command.SETPBIOPORT, Command.VEL2, Command.PTUPOS})


# ----------------------------------------------------------------------------- checksum


def checksum(payload: bytes) -> int:
    """ARCOS checksum of type+data: big-endian 16-bit sums, an odd last byte XORed in.

    The C core (:func:`robocli.core.arcos_checksum`) computes the same on the hot path; this
    one keeps the spec self-contained and is the reference the C tests are checked against.
    """
    n = len(payload)
    even = n - (n & 1)
    c = sum(struct.unpack_from(f">{even // 2}H", payload)) & 0xFFFF if even else 0
    if n & 1:
        c ^= payload[-1]
    return c


# ----------------------------------------------------------------------------- framing

#: One frame on the wire. ``payload`` is the type byte followed by the data.
Frame = Struct(
    "sync" / Const(SYNC),
    "count" / Rebuild(Int8ub, len_(this.payload) + 2),
    "payload" / Bytes(this.count - 2),
    "checksum" / Checksum(Int16ub, lambda data: checksum(data), this.payload),
)


def frame(payload: bytes) -> bytes:
    """Wrap a type byte + data in sync, count and checksum."""
    if not 1 <= len(payload) <= 252:
        raise ValueError(f"ARCOS payload must be 1..252 bytes, got {len(payload)}")
    ck = checksum(payload)
    return SYNC + bytes((len(payload) + 2,)) + payload + bytes((ck >> 8, ck & 0xFF))


def unframe(data: bytes) -> bytes:
    """Check one whole frame and return its payload (type byte + data)."""
    if len(data) < 6 or data[:2] != SYNC:
        raise FramingError(f"not an ARCOS frame: {data[:8].hex(' ')}")
    count = data[2]
    if count < 3 or len(data) != count + 3:
        raise FramingError(f"ARCOS count byte {count} does not match frame length {len(data)}")
    payload = data[3 : 3 + count - 2]
    got = (data[-2] << 8) | data[-1]
    want = checksum(payload)
    if got != want:
        raise ChecksumError(f"ARCOS checksum {got:#06x} != computed {want:#06x}")
    return payload


# ----------------------------------------------------------------------------- client commands


class _SignMagnitude(Adapter):  # type: ignore[misc]
    """``0x3B``/``0x1B`` + unsigned LE magnitude  <->  a signed int (-65535..65535)."""

    def _decode(self, obj: Any, context: Any, path: Any) -> int:
        if obj.argtype not in (ARG_INT, ARG_NINT):
            raise ProtocolError(f"not an int argument type: {obj.argtype:#04x}")
        return -int(obj.magnitude) if obj.argtype == ARG_NINT else int(obj.magnitude)

    def _encode(self, obj: int, context: Any, path: Any) -> dict[str, int]:
        if not -0xFFFF <= obj <= 0xFFFF:
            raise ProtocolError(f"ARCOS int argument out of range: {obj}")
        return {"argtype": ARG_NINT if obj < 0 else ARG_INT, "magnitude": abs(obj)}


IntArg = _SignMagnitude(Struct("argtype" / Int8ub, "magnitude" / Int16ul))

#: String argument; ARIA's ``comStr`` appends a NUL after the counted bytes (kept in ``tail``).
StrArg = Struct(
    "argtype" / Const(ARG_STR, Int8ub),
    "text" / PrefixedArray(Int8ub, Int8ub),
    "tail" / GreedyBytes,
)

#: SIM_SET_POSE: one type byte (ignored by MobileSim), then x, y (mm) and th (deg) int32.
SimPoseArg = Struct("argtype" / Int8ub, "x" / Int32sl, "y" / Int32sl, "th" / Int32sl)


def _arg_kind_of(cmd: int) -> str:
    if cmd == Command.SIM_SET_POSE:
        return "pose"
    if cmd in STRING_COMMANDS:
        return "str"
    return "int"


def _arg_kind(ctx: Any) -> str:
    return _arg_kind_of(int(ctx.command))


#: A client command packet payload (type byte = command number, then the optional argument).
CommandPacket = Struct(
    "command" / Int8ub,
    "arg"
    / Switch(
        _arg_kind,
        {"int": Optional(IntArg), "str": StrArg, "pose": SimPoseArg},
    ),
    "extra" / GreedyBytes,
)


def encode_command(command: int, arg: int | str | bytes | None = None) -> bytes:
    """One framed client command. ``arg``: int (sign-magnitude), str/bytes (string arg)."""
    cmd = int(command)
    if not 0 <= cmd <= 255:
        raise ProtocolError(f"ARCOS command number out of range: {cmd}")
    if arg is None:
        payload = bytes((cmd,))
    elif isinstance(arg, int):
        if not -0xFFFF <= arg <= 0xFFFF:
            raise ProtocolError(f"ARCOS int argument out of range: {arg}")
        # same bytes as IntArg.build(arg), through the struct view of its declaration
        payload = bytes((cmd,)) + _INT_ARG.pack(ARG_NINT if arg < 0 else ARG_INT, abs(arg))
    else:
        text = arg.encode("latin-1") if isinstance(arg, str) else bytes(arg)
        if len(text) > 199:
            raise ProtocolError("ARCOS string arguments are limited to 199 bytes")
        payload = bytes((cmd, ARG_STR, len(text))) + text + b"\x00"
    return frame(payload)


def encode_two_bytes(command: int, high: int, low: int) -> bytes:
    """VEL2 / DIGOUT style: two signed bytes packed in one int, as ARIA's ``com2Bytes``."""
    value = struct.unpack("<h", bytes((low & 0xFF, high & 0xFF)))[0]
    return encode_command(command, value)


def split_two_bytes(value: int) -> tuple[int, int]:
    """Inverse of :func:`encode_two_bytes`: a decoded int arg -> (high, low) signed bytes."""
    raw = struct.pack("<h", max(-32768, min(32767, value)))
    lo, hi = struct.unpack("<bb", raw)
    return hi, lo


def encode_sim_pose(x_mm: int, y_mm: int, th_deg: int) -> bytes:
    """MobileSim SIM_SET_POSE: teleport the true pose."""
    return frame(
        bytes((Command.SIM_SET_POSE,))
        + SimPoseArg.build({"argtype": ARG_INT, "x": x_mm, "y": y_mm, "th": th_deg})
    )


@dataclass(frozen=True)
class DecodedCommand:
    """A client command as the robot reads it."""

    command: int
    arg: int | bytes | tuple[int, int, int] | None

    @property
    def name(self) -> str:
        try:
            return Command(self.command).name
        except ValueError:
            return f"CMD_{self.command}"


def decode_command(payload: bytes) -> DecodedCommand:
    """Parse a client command payload (type byte + argument)."""
    cmd = payload[0]
    if len(payload) == 1:
        return DecodedCommand(cmd, None)
    if len(payload) == 1 + _INT_ARG.size and _arg_kind_of(cmd) == "int":
        # hot path (a robot reads one per command): struct view of IntArg's declaration
        argtype, magnitude = _INT_ARG.unpack_from(payload, 1)
        if argtype in (ARG_INT, ARG_NINT):
            return DecodedCommand(cmd, -magnitude if argtype == ARG_NINT else magnitude)
    parsed = CommandPacket.parse(payload)
    arg: int | bytes | tuple[int, int, int] | None
    raw = parsed.arg
    if raw is None:
        arg = None
    elif isinstance(raw, int):
        arg = raw
    elif "text" in raw:
        arg = bytes(raw.text)
    else:
        arg = (int(raw.x), int(raw.y), int(raw.th))
    return DecodedCommand(int(parsed.command), arg)


# ----------------------------------------------------------------------------- server packets

SyncReply = Struct("name" / CString("utf8"), "type" / CString("utf8"), "subtype" / CString("utf8"))

SonarReading = Struct("number" / Int8ub, "range" / Int16ul)

#: Standard motor SIP body (after the type byte). Fields 13.. are optional trailing groups:
#: a robot sends a prefix of them (MobileSim sends through ``state_of_charge``).
SIP = Struct(
    "x" / Int16ul,
    "y" / Int16ul,
    "th" / Int16sl,
    "lvel" / Int16sl,
    "rvel" / Int16sl,
    "battery" / Int8ub,
    "stall_bumpers" / Int16ul,
    "control" / Int16sl,
    "flags" / Int16ul,
    "compass" / Int8ub,
    "sonar" / PrefixedArray(Int8ub, SonarReading),
    "io"
    / Optional(
        Struct(
            "grip_state" / Int8ub,
            "anport" / Int8ub,
            "analog" / Int8ub,
            "digin" / Int8ub,
            "digout" / Int8ub,
        )
    ),
    "battery_x10" / Optional(Int16ul),
    "charge_state" / Optional(Int8ub),
    "rotvel" / Optional(Int16sl),
    "fault_flags" / Optional(Int16ul),
    "latvel" / Optional(Int16sl),
    "temperature" / Optional(Int8sl),
    "state_of_charge" / Optional(Int8ub),
    "uc_time" / Optional(Int32ul),
    "flags3" / Optional(Int32ul),
)


def _struct_format(con: Construct) -> str:
    """struct-module format (without byte order) of a fixed-size construct declaration."""
    while isinstance(con, Renamed):
        con = con.subcon
    if isinstance(con, Select):  # Optional(x) is Select(x, Pass)
        return _struct_format(con.subcons[0])
    if isinstance(con, FormatField):
        return str(con.fmtstr)[1:]
    if isinstance(con, Struct):
        return "".join(_struct_format(sub) for sub in con.subcons)
    raise TypeError(f"not a fixed-size declaration: {con!r}")


def _field_names(con: Construct) -> list[str]:
    while isinstance(con, (Renamed, Select)):
        con = con.subcon if isinstance(con, Renamed) else con.subcons[0]
    return [sub.name for sub in con.subcons] if isinstance(con, Struct) else []


# The hot path: a struct-module decoder generated from the SIP declaration above
# (construct parses a SIP in ~120 us; this takes a few us). Tests check both agree.
_SIP_SUBCONS = list(SIP.subcons)
_SONAR_AT = [sub.name for sub in _SIP_SUBCONS].index("sonar")
_SIP_HEAD = struct.Struct("<" + "".join(_struct_format(s) for s in _SIP_SUBCONS[:_SONAR_AT]))
_SIP_HEAD_NAMES = tuple(str(s.name) for s in _SIP_SUBCONS[:_SONAR_AT])
_SONAR_ITEM = struct.Struct("<" + _struct_format(SonarReading))
_SIP_GROUPS = [
    (str(s.name), _struct_format(s), tuple(_field_names(s))) for s in _SIP_SUBCONS[_SONAR_AT + 1 :]
]
_SIP_GROUP_STRUCTS = [(name, struct.Struct("<" + f), names) for name, f, names in _SIP_GROUPS]
# One struct per number k of trailing groups present (a robot sends a prefix of them), so a
# SIP's tail is a single unpack: (size, struct, [(name, field names, n values)...]).
_SIP_TAILS = [
    (
        struct.calcsize("<" + "".join(f for _, f, _ in _SIP_GROUPS[:k])),
        struct.Struct("<" + "".join(f for _, f, _ in _SIP_GROUPS[:k])),
        [(name, names, max(1, len(names))) for name, _, names in _SIP_GROUPS[:k]],
    )
    for k in range(len(_SIP_GROUPS), -1, -1)
]
_SIP_ABSENT = {name: None for name, _, _ in _SIP_GROUPS}
_INT_ARG = struct.Struct("<" + _struct_format(IntArg.subcon))


def decode_sip(body: bytes | memoryview) -> dict[str, Any]:
    """Fast SIP body decoder (after the type byte), same result as ``SIP.parse`` but plain
    dicts/tuples: ``sonar`` is a list of ``(number, range)``; absent optional groups are None.
    """
    out: dict[str, Any] = dict(zip(_SIP_HEAD_NAMES, _SIP_HEAD.unpack_from(body, 0), strict=True))
    pos = _SIP_HEAD.size
    k = body[pos]
    pos += 1
    end = pos + k * _SONAR_ITEM.size
    if end > len(body):
        raise ProtocolError(f"SIP announces {k} sonar readings but holds {len(body) - pos} bytes")
    out["sonar"] = list(_SONAR_ITEM.iter_unpack(body[pos:end]))
    out.update(_SIP_ABSENT)
    rest = len(body) - end
    for size, fmt, groups in _SIP_TAILS:
        if size <= rest:
            values = fmt.unpack_from(body, end)
            i = 0
            for name, names, n in groups:
                out[name] = dict(zip(names, values[i : i + n], strict=True)) if names else values[i]
                i += n
            break
    return out


def encode_sip_body(fields: dict[str, Any]) -> bytes:
    """Fast SIP body encoder, the inverse of :func:`decode_sip` (same bytes as ``SIP.build``).

    ``sonar`` is a sequence of ``(number, range)``; the optional trailing groups are written
    in declaration order up to the first one that is missing or None.
    """
    sonar = fields.get("sonar") or ()
    parts = [_SIP_HEAD.pack(*(fields[n] for n in _SIP_HEAD_NAMES)), bytes((len(sonar),))]
    parts.extend(_SONAR_ITEM.pack(num, rng) for num, rng in sonar)
    for name, fmt, names in _SIP_GROUP_STRUCTS:
        value = fields.get(name)
        if value is None:
            break
        parts.append(fmt.pack(*(value[n] for n in names)) if names else fmt.pack(value))
    return b"".join(parts)


#: FLAGS bits of the SIP.
FLAG_MOTORS_ON = 0x0001
FLAG_SONAR_MASK = 0x001E
FLAG_ESTOP = 0x0020
#: STALL_AND_BUMPERS bits.
STALL_LEFT = 0x0001
STALL_RIGHT = 0x0100
BUMPERS_REAR_MASK = 0x00FE
BUMPERS_FRONT_MASK = 0xFE00

#: CONFIG packet body (reply to CONFIG 18), in ARIA's parse order; fields after
#: ``powerbot_charge_threshold`` are optional (MobileSim stops there: 118 data bytes).
CONFIG = Struct(
    "robot_type" / CString("utf8"),
    "subtype" / CString("utf8"),
    "serial" / CString("utf8"),
    "p2os_at" / Int8ub,
    "rotvel_top" / Int16ul,
    "transvel_top" / Int16ul,
    "rotacc_top" / Int16ul,
    "transacc_top" / Int16ul,
    "pwm_max" / Int16ul,
    "name" / CString("utf8"),
    "sip_cycle" / Int8ub,
    "host_baud" / Int8ub,
    "aux1_baud" / Int8ub,
    "has_gripper" / Int16ul,
    "front_sonar" / Int16ul,
    "rear_sonar" / Int8ub,
    "low_battery" / Int16ul,
    "rev_count" / Int16ul,
    "watchdog" / Int16ul,
    "normal_mpacs" / Int8ub,
    "stall_val" / Int16ul,
    "stall_count" / Int16ul,
    "joy_vel" / Int16ul,
    "joy_rotvel" / Int16ul,
    "rotvel_max" / Int16ul,
    "transvel_max" / Int16ul,
    "rot_accel" / Int16ul,
    "rot_decel" / Int16ul,
    "rot_kp" / Int16ul,
    "rot_kv" / Int16ul,
    "rot_ki" / Int16ul,
    "trans_accel" / Int16ul,
    "trans_decel" / Int16ul,
    "trans_kp" / Int16ul,
    "trans_kv" / Int16ul,
    "trans_ki" / Int16ul,
    "front_bumps" / Int8ub,
    "rear_bumps" / Int8ub,
    "charger" / Int8ub,
    "sonar_cycle" / Int8ub,
    "reset_baud" / Int8ub,
    "gyro_type" / Int8ub,
    "drift_factor" / Int16sl,
    "aux2_baud" / Int8ub,
    "aux3_baud" / Int8ub,
    "ticks_mm" / Int16ul,
    "shutdown_volts" / Int16ul,
    "firmware" / CString("utf8"),
    "gyro_cw" / Int16ul,
    "gyro_ccw" / Int16ul,
    "kinematics_delay" / Int8ub,
    "latvel_top" / Int16ul,
    "latacc_top" / Int16ul,
    "latvel_max" / Int16ul,
    "lat_accel" / Int16ul,
    "lat_decel" / Int16ul,
    "powerbot_charge_threshold" / Int16ul,
    "pdb_port" / Optional(Int8ub),
    "gyro_rate_limit" / Optional(Int16ul),
    "high_temp_shutdown" / Optional(Int8sl),
    "power_bits" / Optional(Int16ul),
    "battery_type" / Optional(Int8ub),
    "soc_low" / Optional(Int16ul),
    "soc_shutdown" / Optional(Int16ul),
    "bootloader" / Optional(CString("utf8")),
    "config_flags" / Optional(Int32ul),
    "gyro_fw_version" / Optional(Int16sl),
)

IO = Struct(
    "digin" / PrefixedArray(Int8ub, Int8ub),
    "digout" / PrefixedArray(Int8ub, Int8ub),
    "analog" / PrefixedArray(Int8ub, Int16ul),
)

ENCODER = Struct("left" / Int32sl, "right" / Int32sl)

BATTERY = Struct(
    "count" / Int8ub,
    "bytes_per_battery" / Int8ub,
    "data" / Bytes(this.count * this.bytes_per_battery),
)

#: Server packet body by type byte (SYNC0/1 replies have an empty body).
SERVER_BODIES: dict[int, Construct] = {
    PacketType.SYNC2: SyncReply,
    PacketType.CONFIG: CONFIG,
    PacketType.SIP: SIP,
    PacketType.SIP_MOVING: SIP,
    PacketType.IO: IO,
    PacketType.ENCODER: ENCODER,
    PacketType.BATTERY: BATTERY,
}


def packet_name(ptype: int, *, from_client: bool) -> str:
    """Human name of a packet type byte in one direction."""
    try:
        return (Command(ptype) if from_client else PacketType(ptype)).name
    except ValueError:
        return f"0x{ptype:02X}"


def decode_server(payload: bytes) -> tuple[int, Any]:
    """Parse a server packet payload -> (type, construct Container or raw bytes)."""
    ptype = payload[0]
    body = SERVER_BODIES.get(ptype)
    if body is None:
        return ptype, bytes(payload[1:])
    return ptype, body.parse(payload[1:])


def encode_server(ptype: int, body: dict[str, Any] | None = None) -> bytes:
    """Build one framed server packet from its declaration."""
    spec = SERVER_BODIES.get(int(ptype))
    data = b"" if spec is None or body is None else spec.build(body)
    return frame(bytes((int(ptype),)) + data)


# ----------------------------------------------------------------------------- robot params


@dataclass(frozen=True)
class SonarPose:
    x: float  #: m, forward
    y: float  #: m, left
    th: float  #: rad, CCW from forward


def _poses(rows: list[tuple[int, int, int]]) -> tuple[SonarPose, ...]:
    return tuple(SonarPose(x / 1000.0, y / 1000.0, math.radians(t)) for x, y, t in rows)


_P3DX_SONAR = _poses(
    [(69, 136, 90), (114, 119, 50), (148, 78, 30), (166, 27, 10), (166, -27, -10),
     (148, -78, -30), (114, -119, -50), (69, -136, -90), (-157, -136, -90), (-203, -119, -130),
     (-237, -78, -150), (-255, -27, -170), (-255, 27, 170), (-237, 78, 150), (-203, 119, 130),
     (-157, 136, 90)]
)  # fmt: skip
_P3AT_SONAR = _poses(
    [(147, 136, 90), (193, 119, 50), (227, 79, 30), (245, 27, 10), (245, -27, -10),
     (227, -79, -30), (193, -119, -50), (147, -136, -90), (-144, -136, -90), (-189, -119, -130),
     (-223, -79, -150), (-241, -27, -170), (-241, 27, 170), (-223, 79, 150), (-189, 119, 130),
     (-144, 136, 90)]
)  # fmt: skip
_AMIGO_SH_SONAR = _poses(
    [(70, 100, 90), (125, 75, 41), (144, 30, 15), (144, -30, -15), (120, -75, -41),
     (70, -100, -90), (-146, -58, -145), (-146, 58, 145)]
)  # fmt: skip
_AMIGO_SONAR = _poses(
    [(76, 100, 90), (125, 75, 41), (150, 30, 15), (150, -30, -15), (125, -75, -41),
     (76, -100, -90), (-140, -58, -145), (-140, 58, 145)]
)  # fmt: skip
_PEOPLEBOT_SONAR = _P3DX_SONAR + _poses(
    [(-20, 136, 90), (24, 119, 50), (58, 78, 30), (77, 27, 10), (77, -27, -10), (58, -78, -30),
     (24, -119, -50), (-20, -136, -90), (-191, -136, -90), (-237, -119, -130),
     (-271, -78, -150), (-290, -27, -170), (-290, 27, 170), (-271, 78, 150), (-237, 119, 130),
     (-191, 136, 90)]
)  # fmt: skip
_POWERBOT_SONAR = _poses(
    [(152, 278, 90), (200, 267, 65), (241, 238, 45), (274, 200, 35), (300, 153, 25),
     (320, 96, 15), (332, 33, 5), (0, 0, -180), (332, -33, -5), (320, -96, -15),
     (300, -153, -25), (274, -200, -35), (241, -238, -45), (200, -267, -65), (152, -278, -90),
     (0, 0, -180), (-298, -278, -90), (-347, -267, -115), (-388, -238, -135),
     (-420, -200, -145), (-447, -153, -155), (-467, -96, -165), (-478, -33, -175),
     (0, 0, -180), (-478, 33, 175), (-467, 96, 165), (-447, 153, 155), (-420, 200, 145),
     (-388, 238, 135), (-347, 267, 115), (-298, 278, 90)]
)  # fmt: skip


@dataclass(frozen=True)
class RobotParams:
    """Per-subtype conversion factors and geometry (values of AriaCoda's ``params/*.p``)."""

    subtype: str
    dist_conv: float  #: mm per position unit
    vel_conv: float  #: mm/s per wheel-velocity unit
    diff_conv: float  #: rad/s of rotation per mm/s of wheel-speed difference
    angle_conv: float = 2 * math.pi / 4096  #: rad per heading unit
    range_conv: float = 1.0  #: mm per sonar unit
    vel2_divisor: float = 20.0  #: mm/s per VEL2 byte unit
    radius: float = 0.25  #: m
    width: float = 0.425  #: m
    length_front: float = 0.210  #: m
    length_rear: float = 0.301  #: m
    max_velocity: float = 2.2  #: m/s, absolute
    max_rot_velocity: float = math.radians(500)  #: rad/s, absolute
    sonar: tuple[SonarPose, ...] = field(default=_P3DX_SONAR)
    sonar_max_range: float = 5.0  #: m (MobileSim's p3dx model)


ROBOT_PARAMS: dict[str, RobotParams] = {
    p.subtype: p
    for p in (
        RobotParams("p3dx", dist_conv=0.485, vel_conv=1.0, diff_conv=0.0056),
        RobotParams("p3dx-sh", dist_conv=1.0, vel_conv=1.0, diff_conv=0.0056),
        RobotParams(
            "p3at", dist_conv=0.465, vel_conv=1.0, diff_conv=0.0034, radius=0.5, width=0.505,
            length_front=0.313, length_rear=0.313, max_velocity=1.2,
            max_rot_velocity=math.radians(300), sonar=_P3AT_SONAR,
        ),
        RobotParams(
            "p3at-sh", dist_conv=1.0, vel_conv=1.0, diff_conv=0.0034, radius=0.5, width=0.505,
            length_front=0.313, length_rear=0.313, max_velocity=1.2,
            max_rot_velocity=math.radians(300), sonar=_P3AT_SONAR,
        ),
        RobotParams(
            "amigo", dist_conv=0.5083, vel_conv=0.6154, diff_conv=0.011, radius=0.18,
            width=0.279, length_front=0.16, length_rear=0.17, max_velocity=1.0,
            max_rot_velocity=math.radians(300), sonar=_AMIGO_SONAR,
        ),
        RobotParams(
            "amigo-sh", dist_conv=1.0, vel_conv=1.0, diff_conv=0.011, radius=0.18,
            width=0.279, length_front=0.16, length_rear=0.17, max_velocity=1.0,
            max_rot_velocity=math.radians(300), sonar=_AMIGO_SH_SONAR,
        ),
        RobotParams(
            "peoplebot-sh", dist_conv=1.0, vel_conv=1.0, diff_conv=0.006, radius=0.34,
            width=0.425, length_front=0.2565, length_rear=0.2565, sonar=_PEOPLEBOT_SONAR,
        ),
        RobotParams(
            "powerbot", dist_conv=0.5813, vel_conv=1.0, diff_conv=0.00373, radius=0.55,
            width=0.68, length_front=0.369, length_rear=0.542, max_velocity=2.0,
            max_rot_velocity=math.radians(360), sonar=_POWERBOT_SONAR,
        ),
    )
}  # fmt: skip


# ----------------------------------------------------------------------------- describing


def describe(
    payload: bytes, *, from_client: bool, in_session: bool = True
) -> tuple[str, dict[str, Any]]:
    """Name and decoded fields of one packet payload (type byte + data), for ``dump``.

    Raw units, as on the wire. Before a session (``in_session=False``) client commands 0..2
    without an argument are the handshake's SYNC0/1/2; in a session the same bytes are
    PULSE/OPEN/CLOSE. Undecodable packets give ``{"raw": hex, "error": why}``.
    """
    ptype = payload[0]
    name = packet_name(ptype, from_client=from_client)
    if from_client and not in_session and ptype <= 2 and len(payload) == 1:
        return f"SYNC{ptype}", {}
    try:
        if from_client:
            cmd = decode_command(payload)
            if cmd.arg is None:
                return name, {}
            if cmd.command in TWO_BYTE_COMMANDS and isinstance(cmd.arg, int):
                hi, lo = split_two_bytes(cmd.arg)
                return name, {"arg": cmd.arg, "high": hi, "low": lo}
            if isinstance(cmd.arg, bytes):
                return name, {"arg": cmd.arg.decode("latin-1")}
            return name, {"arg": cmd.arg}
        if ptype & 0xF0 == 0x30:
            return name, decode_sip(payload[1:])
        ptype, body = decode_server(payload)
        if isinstance(body, bytes):
            return name, ({"raw": body.hex()} if body else {})
        return name, plain(body)
    except Exception as exc:  # construct's errors: show the bytes and why
        return name, {"raw": payload[1:].hex(), "error": str(exc).splitlines()[0]}
