"""ARCOS server packets (SYNC replies, SIP, CONFIG, IO, ENCODER, BATTERY) and ``describe``.

Part of :mod:`robocli.protocols.arcos` (import from there).
"""

from __future__ import annotations

import struct
from typing import Any

from construct import (
    Bytes,
    Construct,
    CString,
    Int8sl,
    Int8ub,
    Int16sl,
    Int16ul,
    Int32sl,
    Int32ul,
    Optional,
    PrefixedArray,
    Struct,
    this,
)

from robocli.errors import ProtocolError
from robocli.protocols.arcos.simext import SimLaser, SimLaserPlain, SimStat
from robocli.protocols.arcos.wire import (
    TWO_BYTE_COMMANDS,
    Command,
    PacketType,
    decode_command,
    frame,
    split_two_bytes,
)
from robocli.protocols.common import DECODE_ERRORS, enum_name, plain, undecodable
from robocli.protocols.layout import field_names, struct_codes, struct_of

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


# The hot path: a struct-module decoder generated from the SIP declaration above
# (construct parses a SIP in ~120 us; this takes a few us). Tests check both agree.
_SIP_SUBCONS = list(SIP.subcons)
_SONAR_AT = [sub.name for sub in _SIP_SUBCONS].index("sonar")
_SIP_HEAD = struct.Struct("<" + "".join(struct_codes(s) for s in _SIP_SUBCONS[:_SONAR_AT]))
_SIP_HEAD_NAMES = tuple(str(s.name) for s in _SIP_SUBCONS[:_SONAR_AT])
_SONAR_ITEM = struct_of(SonarReading)
_SIP_GROUPS = [
    (str(s.name), struct_codes(s), field_names(s)) for s in _SIP_SUBCONS[_SONAR_AT + 1 :]
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


def decode_sip(body: bytes | bytearray | memoryview) -> dict[str, Any]:
    """Fast SIP body decoder (after the type byte), same result as ``SIP.parse`` but plain
    dicts/tuples: ``sonar`` is a list of ``(number, range)``; absent optional groups are None.
    Raises :class:`ProtocolError` for a body too short for its fields.
    """
    try:
        head = _SIP_HEAD.unpack_from(body, 0)
        k = body[_SIP_HEAD.size]
    except (struct.error, IndexError) as exc:
        undecodable("ARCOS SIP", body, exc)
    out: dict[str, Any] = dict(zip(_SIP_HEAD_NAMES, head, strict=True))
    pos = _SIP_HEAD.size
    pos += 1
    end = pos + k * _SONAR_ITEM.size
    if end > len(body):
        raise ProtocolError(
            f"ARCOS SIP announces {k} sonar readings but holds {len(body) - pos} bytes"
        )
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
    PacketType.SIM_LASER_A: SimLaserPlain,
    PacketType.SIM_LASER: SimLaser,
    PacketType.SIM_STAT: SimStat,
}


def packet_name(ptype: int, *, from_client: bool) -> str:
    """Human name of a packet type byte in one direction."""
    return enum_name(Command if from_client else PacketType, ptype, f"0x{ptype:02X}")


def _parse(decl: Construct, what: str, body: bytes | bytearray | memoryview) -> Any:
    """``decl.parse(body)``, or a :class:`ProtocolError` naming the packet ``what``."""
    try:
        return decl.parse(bytes(body))
    except DECODE_ERRORS as exc:
        undecodable(f"ARCOS {what}", body, exc)


def parse_sync_reply(body: bytes | bytearray | memoryview) -> tuple[str, str, str]:
    """The SYNC2 reply's data: (robot name, type, subtype)."""
    reply = _parse(SyncReply, "SYNC2 reply", body)
    return str(reply.name), str(reply.type), str(reply.subtype)


def parse_config(body: bytes | bytearray | memoryview) -> dict[str, Any]:
    """The CONFIG packet's data as a dict (raw units; absent optional fields are None)."""
    result: dict[str, Any] = plain(_parse(CONFIG, "CONFIG", body))
    return result


def parse_io(body: bytes | bytearray | memoryview) -> dict[str, Any]:
    """The IO packet's data: ``digin``, ``digout`` (byte lists), ``analog`` (int list)."""
    result: dict[str, Any] = plain(_parse(IO, "IO", body))
    return result


def parse_encoder(body: bytes | bytearray | memoryview) -> tuple[int, int]:
    """The ENCODER packet's data: (left, right) raw encoder counts."""
    enc = _parse(ENCODER, "ENCODER", body)
    return int(enc.left), int(enc.right)


def parse_battery(body: bytes | bytearray | memoryview) -> dict[str, Any]:
    """The BATTERY info packet's data: ``count``, ``bytes_per_battery``, ``data``."""
    result: dict[str, Any] = plain(_parse(BATTERY, "BATTERY", body))
    return result


def decode_body(ptype: int, body: bytes | bytearray | memoryview) -> dict[str, Any] | bytes:
    """The data of a server packet of type ``ptype`` as plain values.

    SIPs through :func:`decode_sip`, declared packets as dicts (the SYNC2 reply included),
    anything else as its raw bytes. Raises :class:`ProtocolError` naming the packet when
    the bytes do not fit its declaration.
    """
    if ptype & 0xF0 == 0x30:
        return decode_sip(body)
    decl = SERVER_BODIES.get(ptype)
    if decl is None:
        return bytes(body)
    result: dict[str, Any] = plain(_parse(decl, packet_name(ptype, from_client=False), body))
    return result


def decode_server(payload: bytes | bytearray | memoryview) -> tuple[int, Any]:
    """Parse a server packet payload -> (type, construct Container or raw bytes).

    Raises :class:`ProtocolError` naming the packet when its data does not fit.
    """
    if not payload:
        raise ProtocolError("empty ARCOS server packet (no type byte)")
    ptype = payload[0]
    decl = SERVER_BODIES.get(ptype)
    if decl is None:
        return ptype, bytes(payload[1:])
    return ptype, _parse(decl, packet_name(ptype, from_client=False), payload[1:])


def encode_server(ptype: int, body: dict[str, Any] | None = None) -> bytes:
    """Build one framed server packet from its declaration."""
    spec = SERVER_BODIES.get(int(ptype))
    data = b"" if spec is None or body is None else spec.build(body)
    return frame(bytes((int(ptype),)) + data)


# ----------------------------------------------------------------------------- describing


def describe(
    payload: bytes, *, from_client: bool, in_session: bool = True
) -> tuple[str, dict[str, Any]]:
    """Name and decoded fields of one packet payload (type byte + data), for ``dump``.

    Raw units, as on the wire. Before a session (``in_session=False``) client commands 0..2
    without an argument are the handshake's SYNC0/1/2; in a session the same bytes are
    PULSE/OPEN/CLOSE. Undecodable packets give ``{"raw": hex, "error": why}``; an empty
    payload raises :class:`ProtocolError`.
    """
    if not payload:
        raise ProtocolError("empty ARCOS packet (no type byte)")
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
        body = decode_body(ptype, payload[1:])
        if isinstance(body, bytes):
            return name, ({"raw": body.hex()} if body else {})
        return name, body
    except ProtocolError as exc:  # every decoder's failure: show the bytes and why
        return name, {"raw": bytes(payload[1:]).hex(), "error": str(exc).splitlines()[0]}
