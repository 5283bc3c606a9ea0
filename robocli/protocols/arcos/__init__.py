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

from robocli.protocols.arcos.packets import (
    BATTERY,
    BUMPERS_FRONT_MASK,
    BUMPERS_REAR_MASK,
    CONFIG,
    ENCODER,
    FLAG_ESTOP,
    FLAG_MOTORS_ON,
    FLAG_SONAR_MASK,
    IO,
    SERVER_BODIES,
    SIP,
    STALL_LEFT,
    STALL_RIGHT,
    SonarReading,
    SyncReply,
    decode_body,
    decode_server,
    decode_sip,
    describe,
    encode_server,
    encode_sip_body,
    packet_name,
    parse_battery,
    parse_config,
    parse_encoder,
    parse_io,
    parse_sync_reply,
)
from robocli.protocols.arcos.wire import (
    ARG_INT,
    ARG_NINT,
    ARG_STR,
    MAX_PAYLOAD,
    STRING_COMMANDS,
    SYNC,
    TWO_BYTE_COMMANDS,
    Command,
    CommandPacket,
    DecodedCommand,
    Frame,
    IntArg,
    PacketType,
    SimPoseArg,
    StrArg,
    checksum,
    decode_command,
    encode_command,
    encode_sim_pose,
    encode_two_bytes,
    frame,
    split_two_bytes,
    unframe,
)

__all__ = [
    "ARG_INT",
    "ARG_NINT",
    "ARG_STR",
    "BATTERY",
    "BUMPERS_FRONT_MASK",
    "BUMPERS_REAR_MASK",
    "CONFIG",
    "Command",
    "CommandPacket",
    "DecodedCommand",
    "ENCODER",
    "FLAG_ESTOP",
    "FLAG_MOTORS_ON",
    "FLAG_SONAR_MASK",
    "Frame",
    "IO",
    "IntArg",
    "MAX_PAYLOAD",
    "PacketType",
    "SERVER_BODIES",
    "SIP",
    "STALL_LEFT",
    "STALL_RIGHT",
    "STRING_COMMANDS",
    "SYNC",
    "SimPoseArg",
    "SonarReading",
    "StrArg",
    "SyncReply",
    "TWO_BYTE_COMMANDS",
    "checksum",
    "decode_body",
    "decode_command",
    "decode_server",
    "decode_sip",
    "describe",
    "encode_command",
    "encode_server",
    "encode_sim_pose",
    "encode_sip_body",
    "encode_two_bytes",
    "frame",
    "packet_name",
    "parse_battery",
    "parse_config",
    "parse_encoder",
    "parse_io",
    "parse_sync_reply",
    "split_two_bytes",
    "unframe",
]
