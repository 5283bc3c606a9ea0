"""ARCOS wire basics: command and packet numbers, checksum, framing, client commands.

Part of :mod:`robocli.protocols.arcos` (import from there).
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass
from typing import Any

from construct import (
    Adapter,
    Bytes,
    Checksum,
    Const,
    GreedyBytes,
    Int8ub,
    Int16ub,
    Int16ul,
    Int32sl,
    Optional,
    PrefixedArray,
    Rebuild,
    Struct,
    Switch,
    ValidationError,
    len_,
    this,
)

from robocli.errors import ChecksumError, FramingError, ProtocolError
from robocli.protocols.common import DECODE_ERRORS, enum_name, undecodable
from robocli.protocols.layout import struct_of

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
            raise ValidationError(f"not an int argument type: {obj.argtype:#04x}", path=path)
        return -int(obj.magnitude) if obj.argtype == ARG_NINT else int(obj.magnitude)

    def _encode(self, obj: int, context: Any, path: Any) -> dict[str, int]:
        if not -0xFFFF <= obj <= 0xFFFF:
            raise ProtocolError(f"ARCOS int argument out of range: {obj}")
        return {"argtype": ARG_NINT if obj < 0 else ARG_INT, "magnitude": abs(obj)}


IntArg = _SignMagnitude(Struct("argtype" / Int8ub, "magnitude" / Int16ul))

#: struct view of IntArg (the hot path of encode/decode_command)
_INT_ARG = struct_of(IntArg.subcon)

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
        return enum_name(Command, self.command, f"CMD_{self.command}")


def decode_command(payload: bytes | bytearray | memoryview) -> DecodedCommand:
    """Parse a client command payload (type byte + argument).

    Raises :class:`ProtocolError` naming the command when the argument does not fit.
    """
    if not payload:
        raise ProtocolError("empty ARCOS command packet (no command byte)")
    cmd = payload[0]
    if len(payload) == 1:
        return DecodedCommand(cmd, None)
    if len(payload) == 1 + _INT_ARG.size and _arg_kind_of(cmd) == "int":
        # hot path (a robot reads one per command): struct view of IntArg's declaration
        argtype, magnitude = _INT_ARG.unpack_from(payload, 1)
        if argtype in (ARG_INT, ARG_NINT):
            return DecodedCommand(cmd, -magnitude if argtype == ARG_NINT else magnitude)
    try:
        parsed = CommandPacket.parse(bytes(payload))
    except DECODE_ERRORS as exc:
        undecodable(f"ARCOS command {enum_name(Command, cmd, f'CMD_{cmd}')}", payload, exc)
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
