"""Open Interface sensor packets 7..58 and their groups, declared once with ``construct``, and
the stream's frames (opcode 148's output).

A sensor packet's data is big-endian, 1 or 2 bytes, signed or not as :data:`PACKETS` says.
A group (0..6, 100, 101, 106, 107) is its packets' data back to back, in id order. A query
list (149) answers its packets' data back to back, without ids. A stream frame is::

    19  n  [id data]...  checksum      (n: bytes between n and the checksum; the low byte of
                                          the sum of every byte of the frame is 0)

Part of :mod:`robocli.protocols.create_oi` (import from there).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

import construct as cs

from robocli.errors import ChecksumError, FramingError, InvalidArgument, ProtocolError
from robocli.protocols.common import DECODE_ERRORS, plain

__all__ = [
    "GROUPS",
    "MODES",
    "PACKETS",
    "STREAM_HEADER",
    "build_stream",
    "decode_packets",
    "encode_packets",
    "packet_ids",
    "packet_size",
    "parse_stream",
]

_U8, _S8, _U16, _S16 = cs.Int8ub, cs.Int8sb, cs.Int16ub, cs.Int16sb

#: packet id -> (field name, declaration). Ranges as the specification states them; 32 and
#: 33 are unused on the Create 2 (1 and 2 bytes), 16 too (1 byte).
PACKETS: dict[int, tuple[str, Any]] = {
    7: ("bumps_wheel_drops", _U8),  # bit 0 bump right, 1 bump left, 2 drop right, 3 drop left
    8: ("wall", _U8),
    9: ("cliff_left", _U8),
    10: ("cliff_front_left", _U8),
    11: ("cliff_front_right", _U8),
    12: ("cliff_right", _U8),
    13: ("virtual_wall", _U8),
    14: ("wheel_overcurrents", _U8),
    15: ("dirt_detect", _U8),
    16: ("unused_16", _U8),
    17: ("ir_omni", _U8),
    18: ("buttons", _U8),
    19: ("distance", _S16),  # mm since the last read
    20: ("angle", _S16),  # degrees since the last read, counter-clockwise positive
    21: ("charging_state", _U8),
    22: ("voltage", _U16),  # mV
    23: ("current", _S16),  # mA, negative: discharging
    24: ("temperature", _S8),  # degrees C
    25: ("battery_charge", _U16),  # mAh
    26: ("battery_capacity", _U16),  # mAh
    27: ("wall_signal", _U16),
    28: ("cliff_left_signal", _U16),
    29: ("cliff_front_left_signal", _U16),
    30: ("cliff_front_right_signal", _U16),
    31: ("cliff_right_signal", _U16),
    32: ("unused_32", _U8),
    33: ("unused_33", _U16),
    34: ("charging_sources", _U8),
    35: ("oi_mode", _U8),  # 0 off, 1 passive, 2 safe, 3 full
    36: ("song_number", _U8),
    37: ("song_playing", _U8),
    38: ("stream_packets", _U8),
    39: ("requested_velocity", _S16),  # mm/s
    40: ("requested_radius", _S16),  # mm
    41: ("requested_right_velocity", _S16),  # mm/s
    42: ("requested_left_velocity", _S16),  # mm/s
    43: ("left_encoder_counts", _S16),  # rolls over
    44: ("right_encoder_counts", _S16),
    45: ("light_bumper", _U8),
    46: ("light_bump_left", _U16),
    47: ("light_bump_front_left", _U16),
    48: ("light_bump_center_left", _U16),
    49: ("light_bump_center_right", _U16),
    50: ("light_bump_front_right", _U16),
    51: ("light_bump_right", _U16),
    52: ("ir_left", _U8),
    53: ("ir_right", _U8),
    54: ("left_motor_current", _S16),  # mA
    55: ("right_motor_current", _S16),
    56: ("main_brush_current", _S16),
    57: ("side_brush_current", _S16),
    58: ("stasis", _U8),
}

#: group id -> its packet ids, in order.
GROUPS: dict[int, tuple[int, ...]] = {
    0: tuple(range(7, 27)),
    1: tuple(range(7, 17)),
    2: tuple(range(17, 21)),
    3: tuple(range(21, 27)),
    4: tuple(range(27, 35)),
    5: tuple(range(35, 43)),
    6: tuple(range(7, 43)),
    100: tuple(range(7, 59)),
    101: tuple(range(43, 59)),
    106: tuple(range(46, 52)),
    107: tuple(range(54, 59)),
}

MODES = ("off", "passive", "safe", "full")  #: packet 35's values, by number
STREAM_HEADER = 19
_PACKET_STRUCTS = {pid: cs.Struct(name / decl) for pid, (name, decl) in PACKETS.items()}
_GROUP_STRUCTS = {
    gid: cs.Struct(*(PACKETS[p][0] / PACKETS[p][1] for p in ids)) for gid, ids in GROUPS.items()
}
_SIZES = {pid: s.sizeof() for pid, s in _PACKET_STRUCTS.items()} | {
    gid: s.sizeof() for gid, s in _GROUP_STRUCTS.items()
}


def packet_size(pid: int) -> int:
    """Data bytes of packet or group ``pid``; :class:`~robocli.errors.ProtocolError` if no
    such packet exists."""
    try:
        size: int = _SIZES[pid]
    except KeyError:
        raise ProtocolError(f"no sensor packet {pid}") from None
    return size


def packet_ids(pid: int) -> tuple[int, ...]:
    """The single packets that packet or group ``pid`` is made of."""
    if pid in GROUPS:
        return GROUPS[pid]
    packet_size(pid)
    return (pid,)


def _decl(pid: int) -> Any:
    return _GROUP_STRUCTS[pid] if pid in GROUPS else _PACKET_STRUCTS[pid]


def _clamp(decl: Any, value: int) -> int:
    bits = 8 * decl.sizeof()
    lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if decl.fmtstr[-1].islower() else (
        0, (1 << bits) - 1)  # fmt: skip
    return lo if value < lo else hi if value > hi else value


def encode_packets(pids: Iterable[int], values: Mapping[str, int]) -> bytes:
    """The data of packets or groups ``pids`` back to back (a query list's answer), from
    ``values`` (field name -> integer, clamped to the field's range; a missing one is 0)."""
    out = bytearray()
    for pid in pids:
        packet_size(pid)
        for p in packet_ids(pid):
            name, decl = PACKETS[p]
            out += decl.build(_clamp(decl, int(values.get(name, 0))))
    return bytes(out)


def decode_packets(pids: Iterable[int], data: bytes) -> dict[str, int]:
    """Field name -> value of packets or groups ``pids`` read back to back from ``data``
    (exactly their size). Raises :class:`~robocli.errors.ProtocolError`."""
    out: dict[str, int] = {}
    view = memoryview(data)
    pos = 0
    for pid in pids:
        n = packet_size(pid)
        if pos + n > len(view):
            raise ProtocolError(f"packet {pid}: {len(view) - pos} of its {n} bytes")
        try:
            out.update(plain(_decl(pid).parse(view[pos : pos + n])))
        except DECODE_ERRORS as exc:  # pragma: no cover - sizes are checked above
            raise ProtocolError(f"packet {pid}: {exc}") from exc
        pos += n
    if pos != len(view):
        raise ProtocolError(f"{len(view) - pos} bytes past the packets' end")
    return out


def build_stream(pids: Iterable[int], values: Mapping[str, int]) -> bytes:
    """One stream frame of packets ``pids`` (each id, then its data)."""
    body = bytearray()
    for pid in pids:
        body.append(pid)
        body += encode_packets((pid,), values)
    if len(body) > 255:
        raise InvalidArgument(f"stream frame of {len(body)} bytes: at most 255")
    frame = bytes([STREAM_HEADER, len(body)]) + body
    return frame + bytes([-sum(frame) & 0xFF])


def parse_stream(frame: bytes) -> list[tuple[int, dict[str, int]]]:
    """(packet id, its fields) of one whole stream frame. Raises
    :class:`~robocli.errors.FramingError` for a bad header or length,
    :class:`~robocli.errors.ChecksumError` for a bad checksum and
    :class:`~robocli.errors.ProtocolError` for an unknown packet id or a cut packet."""
    if len(frame) < 3 or frame[0] != STREAM_HEADER or frame[1] + 3 != len(frame):
        raise FramingError(f"not a stream frame: {bytes(frame[:8]).hex(' ')}")
    if sum(frame) & 0xFF:
        raise ChecksumError(f"stream frame checksum: sum is 0x{sum(frame) & 0xFF:02x}, not 0")
    out: list[tuple[int, dict[str, int]]] = []
    body = frame[2:-1]
    pos = 0
    while pos < len(body):
        pid = body[pos]
        n = packet_size(pid)
        out.append((pid, decode_packets((pid,), body[pos + 1 : pos + 1 + n])))
        pos += 1 + n
    return out
