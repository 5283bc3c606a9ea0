"""iRobot Create 2 Open Interface (OI): the serial protocol of the Create 2 and Roomba 600s.

Facts from iRobot's public "Create 2 Open Interface (OI) Specification based on the iRobot
Roomba 600" (opcodes, data bytes, sensor packets 7..58, their sizes and signedness, groups
0..6, 100, 101, 106, 107, the stream's frame); pycreate2 (MIT) was read to check what a
toolkit sends. This package knows bytes and field meanings only; the simulator is built on it.

Wire format (115200 8N1 by default)::

    command   opcode [data bytes]             (137 vh vl rh rl: drive 0x00c8 mm/s, radius)
    sensors   142 id        -> the packet's (or group's) data, big-endian
    query     149 n id...   -> the packets' data back to back, no ids
    stream    148 n id...   -> every 15 ms: 19 n-bytes [id data]... checksum

Modules: :mod:`~robocli.protocols.create_oi.commands` (opcodes, their data declared with
``construct``, built and parsed), :mod:`~robocli.protocols.create_oi.sensors` (sensor
packets and groups, the stream's frames) and :mod:`~robocli.protocols.create_oi.framing`
(the command framer, and the stream framer of a client: both resynchronise on garbage and
count what they drop).

Choices where sources differ: encoder counts (43, 44) are signed as the specification says
(pycreate2 reads them unsigned; the bits are the same); packets 32 and 33 are 1 and 2 bytes
(the Create 2 sizes; pycreate2's table says 3 and 3, but its group-100 decoder uses 1 and 2).
"""

from __future__ import annotations

from robocli.protocols.create_oi.commands import (
    BAUD_RATES,
    DRIVE_STRAIGHT,
    DRIVE_STRAIGHT_ALT,
    MAX_COMMAND,
    MAX_SONG_NOTES,
    PARAMS,
    SONGS,
    TURN_CCW,
    TURN_CW,
    Op,
    build_command,
    command_length,
    parse_command,
)
from robocli.protocols.create_oi.framing import CommandFramer, StreamFramer
from robocli.protocols.create_oi.sensors import (
    GROUPS,
    MODES,
    PACKETS,
    STREAM_HEADER,
    build_stream,
    decode_packets,
    encode_packets,
    packet_ids,
    packet_size,
    parse_stream,
)

__all__ = [
    "BAUD_RATES",
    "DRIVE_STRAIGHT",
    "DRIVE_STRAIGHT_ALT",
    "GROUPS",
    "MAX_COMMAND",
    "MAX_SONG_NOTES",
    "MODES",
    "PACKETS",
    "PARAMS",
    "SONGS",
    "STREAM_HEADER",
    "TURN_CCW",
    "TURN_CW",
    "CommandFramer",
    "StreamFramer",
    "Op",
    "build_command",
    "build_stream",
    "command_length",
    "decode_packets",
    "encode_packets",
    "packet_ids",
    "packet_size",
    "parse_command",
    "parse_stream",
]
