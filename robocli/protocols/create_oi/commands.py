"""Open Interface commands: every opcode's data bytes declared once with ``construct``, built
by :func:`build_command` and parsed by :func:`parse_command`.

A command is an opcode byte followed by a fixed number of data bytes, except the song (140:
number, length, then ``length`` note/duration pairs), the stream (148) and the query list
(149) (a count, then that many packet ids). :func:`command_length` says how long a command
is from its first bytes; the command framer and the simulator are built on it.

Part of :mod:`robocli.protocols.create_oi` (import from there).
"""

from __future__ import annotations

import enum
from typing import Any

import construct as cs

from robocli.errors import InvalidArgument, ProtocolError
from robocli.protocols.common import DECODE_ERRORS, plain

__all__ = [
    "BAUD_RATES",
    "DRIVE_STRAIGHT",
    "DRIVE_STRAIGHT_ALT",
    "MAX_COMMAND",
    "MAX_SONG_NOTES",
    "PARAMS",
    "SONGS",
    "TURN_CCW",
    "TURN_CW",
    "Op",
    "build_command",
    "command_length",
    "parse_command",
]


class Op(enum.IntEnum):
    """Opcodes of the Create 2 Open Interface (iRobot Create 2 OI Specification)."""

    RESET = 7
    START = 128
    BAUD = 129
    CONTROL = 130  #: the Roomba 500's name for SAFE; the same command
    SAFE = 131
    FULL = 132
    POWER = 133
    SPOT = 134
    CLEAN = 135
    MAX = 136
    DRIVE = 137
    MOTORS = 138
    LEDS = 139
    SONG = 140
    PLAY = 141
    SENSORS = 142
    SEEK_DOCK = 143
    PWM_MOTORS = 144
    DRIVE_DIRECT = 145
    DRIVE_PWM = 146
    STREAM = 148
    QUERY_LIST = 149
    PAUSE_RESUME_STREAM = 150
    SCHEDULING_LEDS = 162
    DIGIT_LEDS_RAW = 163
    DIGIT_LEDS_ASCII = 164
    BUTTONS = 165
    SCHEDULE = 167
    SET_DAY_TIME = 168
    STOP = 173


#: Drive (137) radius values with a special meaning; any other is a turn radius in mm
#: (positive: turn left), -2000..2000.
DRIVE_STRAIGHT = -0x8000  #: 0x8000 on the wire (32768 unsigned), as the signed field reads it
DRIVE_STRAIGHT_ALT = 0x7FFF
TURN_CW = -1  #: turn in place clockwise
TURN_CCW = 1  #: turn in place counter-clockwise

SONGS = 5  #: song numbers 0..4
MAX_SONG_NOTES = 16
#: Baud (129) codes -> bits per second.
BAUD_RATES = (300, 600, 1200, 2400, 4800, 9600, 14400, 19200, 28800, 38400, 57600, 115200)

_NONE = cs.Struct()
#: opcodes without data bytes
_BARE = (Op.RESET, Op.START, Op.CONTROL, Op.SAFE, Op.FULL, Op.POWER, Op.SPOT, Op.CLEAN,
         Op.MAX, Op.SEEK_DOCK, Op.STOP)  # fmt: skip
_U8 = cs.Int8ub
_IDS = cs.Struct("count" / _U8, "packets" / cs.Array(cs.this.count, _U8))

#: opcode -> declaration of its data bytes (after the opcode).
PARAMS: dict[Op, Any] = {
    **dict.fromkeys(_BARE, _NONE),
    Op.BAUD: cs.Struct("code" / _U8),
    Op.DRIVE: cs.Struct("velocity" / cs.Int16sb, "radius" / cs.Int16sb),
    Op.MOTORS: cs.Struct("bits" / _U8),
    Op.LEDS: cs.Struct("bits" / _U8, "color" / _U8, "intensity" / _U8),
    Op.SONG: cs.Struct(
        "number" / _U8,
        "length" / _U8,
        "notes" / cs.Array(cs.this.length, cs.Struct("note" / _U8, "duration" / _U8)),
    ),
    Op.PLAY: cs.Struct("number" / _U8),
    Op.SENSORS: cs.Struct("packet" / _U8),
    Op.PWM_MOTORS: cs.Struct("main" / cs.Int8sb, "side" / cs.Int8sb, "vacuum" / _U8),
    Op.DRIVE_DIRECT: cs.Struct("right" / cs.Int16sb, "left" / cs.Int16sb),  # mm/s
    Op.DRIVE_PWM: cs.Struct("right" / cs.Int16sb, "left" / cs.Int16sb),  # -255..255
    Op.STREAM: _IDS,
    Op.QUERY_LIST: _IDS,
    Op.PAUSE_RESUME_STREAM: cs.Struct("resume" / _U8),
    Op.SCHEDULING_LEDS: cs.Struct("weekdays" / _U8, "scheduling" / _U8),
    Op.DIGIT_LEDS_RAW: cs.Struct("digits" / cs.Bytes(4)),
    Op.DIGIT_LEDS_ASCII: cs.Struct("digits" / cs.Bytes(4)),
    Op.BUTTONS: cs.Struct("bits" / _U8),
    Op.SCHEDULE: cs.Struct("days" / _U8, "times" / cs.Bytes(14)),
    Op.SET_DAY_TIME: cs.Struct("day" / _U8, "hour" / _U8, "minute" / _U8),
}

_FIXED: dict[int, int] = {int(op): 1 + d.sizeof() for op, d in PARAMS.items()
                          if op not in (Op.SONG, Op.STREAM, Op.QUERY_LIST)}  # fmt: skip
#: Longest command: a stream or query list of 255 packet ids.
MAX_COMMAND = 2 + 255


def command_length(head: bytes | bytearray) -> int | None:
    """Length in bytes of the command that starts ``head`` (opcode first); None while
    ``head`` is too short to tell. Raises :class:`~robocli.errors.ProtocolError` for a
    byte that is no opcode, or a song whose number or length is out of range."""
    op = head[0]
    fixed = _FIXED.get(op)
    if fixed is not None:
        return fixed
    if op == Op.SONG:
        if len(head) < 3:
            if len(head) == 2 and head[1] >= SONGS:
                raise ProtocolError(f"song number {head[1]} is not 0..{SONGS - 1}")
            return None
        if head[1] >= SONGS or not 1 <= head[2] <= MAX_SONG_NOTES:
            raise ProtocolError(f"song {head[1]} of {head[2]} notes: out of range")
        return 3 + 2 * head[2]
    if op in (Op.STREAM, Op.QUERY_LIST):
        return None if len(head) < 2 else 2 + head[1]
    raise ProtocolError(f"0x{op:02x} is no Open Interface opcode")


def build_command(op: Op | int, **params: Any) -> bytes:
    """The bytes of one command (``build_command(Op.DRIVE, velocity=200, radius=-1)``).
    Raises :class:`~robocli.errors.InvalidArgument` for a value its field cannot hold."""
    op = Op(op)
    decl = PARAMS[op]
    if op in (Op.STREAM, Op.QUERY_LIST) and "count" not in params:
        params = {**params, "count": len(params.get("packets", ()))}
    if op == Op.SONG and "length" not in params:
        params = {**params, "length": len(params.get("notes", ()))}
    try:
        return bytes([op]) + bytes(decl.build(params))
    except DECODE_ERRORS as exc:
        raise InvalidArgument(f"{op.name}: {exc}") from exc


def parse_command(data: bytes) -> tuple[Op, dict[str, Any]]:
    """(opcode, its data as a dict) of one whole command. Raises
    :class:`~robocli.errors.ProtocolError` for an unknown opcode or a wrong length."""
    if not data:
        raise ProtocolError("empty command")
    length = command_length(data[:3])
    if length is None or length != len(data):
        raise ProtocolError(f"command 0x{data[0]:02x} of {len(data)} bytes: wrong length")
    op = Op(data[0])
    try:
        return op, plain(PARAMS[op].parse(data[1:]))
    except DECODE_ERRORS as exc:  # pragma: no cover - lengths are checked above
        raise ProtocolError(f"{op.name}: {exc}") from exc
