"""MobileSim/AMRISim extensions of ARCOS: simulated laser (0x60, 0x61), SIMSTAT (0x62), SETO data.

Part of :mod:`robocli.protocols.arcos` (import from there). Facts from
``docs/protocols/arcos-sim.md``, checked on the recorded traces h, i, j, k.

Each packet is declared once with ``construct``; the hot paths (six laser packets per SIP
cycle, both in the simulator and in the client) read and write the same bytes through
``struct`` views generated from these declarations (:mod:`robocli.protocols.layout`); no
NumPy here, so the client's import stays light.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from construct import Int8ub, Int16sl, Int16ul, Int32sl, Int32ul, PrefixedArray, Struct

from robocli.errors import ProtocolError
from robocli.protocols.arcos.wire import PacketType, frame
from robocli.protocols.layout import struct_codes, struct_of

__all__ = [
    "LASER_MAX_READINGS",
    "LASER_MAX_TOTAL",
    "LASER_NO_RETURN_MM",
    "SIMSTAT_FLAG_GEOREF",
    "SIMSTAT_FLAG_ODOM_ERROR",
    "SIM_LASER_MOVED",
    "LaserPacket",
    "LaserRange",
    "LaserReading",
    "SetoArg",
    "SimLaser",
    "SimLaserPlain",
    "SimStat",
    "decode_laser",
    "decode_seto",
    "decode_simstat",
    "encode_laser_scan",
    "encode_simstat",
    "laser_bearings",
    "laser_count",
    "laser_fov",
]

LASER_MAX_READINGS = 32  #: readings per laser packet at most
LASER_MAX_TOTAL = 8192  #: readings per scan at most (robocli's bound; 0.05 deg over 360: 7201)
LASER_NO_RETURN_MM = 32767  #: "no return" of the p3dx's LMS200 model: its maximum range, mm
SIM_LASER_MOVED = 0x01  #: 0x61 flags bit0: moved by SIM_SET_POSE since the last scan
SIMSTAT_FLAG_GEOREF = 0x02  #: the map is georeferenced: latitude/longitude/altitude valid
SIMSTAT_FLAG_ODOM_ERROR = 0x04  #: the odometry-error fields are valid

#: One reading of the plain packet: range, mm.
LaserRange = Int16ul
#: One reading of the extended packet: range (mm), reflectance, two reserved bytes (0).
LaserReading = Struct("range" / Int16ul, "reflectance" / Int8ub, "reserved" / Int16ul)

_PLAIN_HEAD = Struct(
    "x" / Int16sl,  # odometric pose, mm (not SIP units)
    "y" / Int16sl,
    "th" / Int16sl,  # whole degrees
    "total" / Int16ul,  # readings in the whole scan
    "first" / Int16ul,  # index of this packet's first reading
)
#: 0x60 (laser enabled with 1): odometric pose, scan position, ranges in mm.
SimLaserPlain = Struct(*_PLAIN_HEAD.subcons, "ranges" / PrefixedArray(Int8ub, LaserRange))

_EXT_HEAD = Struct("total" / Int16ul, "first" / Int16ul)
_EXT_TAIL = Struct("device" / Int8ub, "flags" / Int8ub)
#: 0x61 (laser enabled with 2, what ARIA asks for): readings with reflectance, device, flags.
SimLaser = Struct(
    *_EXT_HEAD.subcons, "readings" / PrefixedArray(Int8ub, LaserReading), *_EXT_TAIL.subcons
)

#: 0x62, the reply to SIM_STAT (237): always 56 data bytes, every field present.
SimStat = Struct(
    "str1" / Int8ub,  # an empty string (0), kept for compatibility
    "str2" / Int8ub,  # a second empty string (0)
    "flags" / Int32ul,  # bit1 georeferenced, bit2 odometry error valid
    "sim_interval" / Int16ul,  # ms of simulated time per step
    "real_interval" / Int16ul,  # ms of real time per step (configured)
    "last_interval" / Int16ul,  # ms, measured duration of the last step
    "x" / Int32sl,  # true pose: mm
    "y" / Int32sl,
    "z" / Int32sl,
    "th" / Int32sl,  # degrees, -180..180
    "latitude" / Int32sl,  # degrees x 1e7
    "longitude" / Int32sl,  # degrees x 1e7
    "altitude" / Int32sl,  # cm
    "gps_dop" / Int32sl,  # DOP x 100; 0 in a bad-GPS sector, -1 without georeference
    "odom_error_x" / Int32sl,  # fractional scale error of x displacement x 1e10
    "odom_error_y" / Int32sl,
    "odom_error_th" / Int32sl,  # fractional rotation error x (180/pi) x 1e7
)

#: SETO's data as AMRISim reads it: a type byte (ignored), then x, y (mm), th (deg) int16.
SetoArg = Struct("argtype" / Int8ub, "x" / Int16sl, "y" / Int16sl, "th" / Int16sl)

# struct views of the declarations above (the per-cycle path)
_PLAIN = struct_of(_PLAIN_HEAD, "SimLaserPlain head")
_EXT = struct_of(_EXT_HEAD, "SimLaser head")
_TAIL = struct_of(_EXT_TAIL, "SimLaser tail")
_SIMSTAT = struct_of(SimStat, "SimStat")
_SIMSTAT_NAMES = tuple(str(s.name) for s in SimStat.subcons)
_SETO = struct_of(SetoArg, "SetoArg")


_RANGE_CODE = struct_codes(LaserRange, "LaserRange")
_READING_CODES = struct_codes(LaserReading, "LaserReading")
_READING_SIZE = struct.calcsize("<" + _READING_CODES)


@dataclass(frozen=True)
class LaserPacket:
    """One decoded laser packet (either format). Ranges in mm."""

    total: int  #: readings in the whole scan
    first: int  #: index of this packet's first reading
    ranges: tuple[int, ...]
    reflectance: tuple[int, ...] | None  #: None for the plain 0x60 format
    pose: tuple[int, int, int] | None  #: 0x60 only: odometric x, y (mm), th (deg)
    flags: int  #: 0x61 only (bit0: moved by SIM_SET_POSE), 0 for 0x60

    @property
    def last(self) -> bool:
        """This packet completes its scan (``first + n >= total``, as ARIA tests it)."""
        return self.first + len(self.ranges) >= self.total


def _short(what: str, body: bytes) -> ProtocolError:
    return ProtocolError(f"ARCOS {what} of {len(body)} bytes does not fit its declaration: "
                         f"{body[:16].hex(' ')}")  # fmt: skip


def decode_laser(ptype: int, body: bytes | bytearray | memoryview) -> LaserPacket:
    """A 0x60 or 0x61 packet's data (after the type byte). Raises :class:`ProtocolError`
    when the bytes do not fit the declaration (same values as ``SimLaser[Plain].parse``)."""
    data = bytes(body)
    if ptype == PacketType.SIM_LASER_A:
        if len(data) < _PLAIN.size + 1:
            raise _short("SIM_LASER_A", data)
        x, y, th, total, first = _PLAIN.unpack_from(data, 0)
        n = data[_PLAIN.size]
        if len(data) != _PLAIN.size + 1 + 2 * n:
            raise _short("SIM_LASER_A", data)
        ranges = struct.unpack_from(f"<{n}{_RANGE_CODE}", data, _PLAIN.size + 1)
        return LaserPacket(total, first, ranges, None, (x, y, th), 0)
    if ptype != PacketType.SIM_LASER:
        raise ProtocolError(f"ARCOS packet 0x{ptype:02X} is not a laser packet")
    if len(data) < _EXT.size + 1:
        raise _short("SIM_LASER", data)
    total, first = _EXT.unpack_from(data, 0)
    n = data[_EXT.size]
    end = _EXT.size + 1 + n * _READING_SIZE
    if len(data) != end + _TAIL.size:
        raise _short("SIM_LASER", data)
    flat = struct.unpack_from("<" + _READING_CODES * n, data, _EXT.size + 1)
    k = len(_READING_CODES)
    _device, flags = _TAIL.unpack_from(data, end)
    return LaserPacket(total, first, flat[0::k], flat[1::k], None, flags)


def encode_laser_scan(
    ranges_mm: Sequence[int],
    *,
    extended: bool,
    reflectance: Sequence[int] | None = None,
    pose: tuple[int, int, int] = (0, 0, 0),
    flags: int = 0,
) -> bytes:
    """One complete scan as framed packets of at most 32 readings (``first`` = 0, 32, ...).

    ``extended``: the 0x61 layout (reflectance, device 0, ``flags`` in the first packet only),
    else 0x60 with the odometric ``pose`` (mm, mm, deg) in every packet. Ranges are clipped to
    0..65535 mm. An empty scan gives no packet.
    """
    rng = [min(0xFFFF, max(0, int(r))) for r in ranges_mm]
    total = len(rng)
    out = []
    if extended:
        refl = [min(255, max(0, int(v))) for v in reflectance] if reflectance else [0] * total
        for first in range(0, total, LASER_MAX_READINGS):
            n = min(LASER_MAX_READINGS, total - first)
            flat = [v for i in range(first, first + n) for v in (rng[i], refl[i], 0)]
            body = struct.pack("<" + _READING_CODES * n, *flat)
            head = _EXT.pack(total, first) + bytes((n,))
            tail = _TAIL.pack(0, flags if first == 0 else 0)
            out.append(frame(bytes((PacketType.SIM_LASER,)) + head + body + tail))
    else:
        x, y, th = (max(-32768, min(32767, int(v))) for v in pose)
        for first in range(0, total, LASER_MAX_READINGS):
            part = rng[first : first + LASER_MAX_READINGS]
            head = _PLAIN.pack(x, y, th, total, first) + bytes((len(part),))
            body = struct.pack(f"<{len(part)}{_RANGE_CODE}", *part)
            out.append(frame(bytes((PacketType.SIM_LASER_A,)) + head + body))
    return b"".join(out)


def laser_fov(start_deg: float, end_deg: float) -> float:
    """Width (deg) of the field of view a client set: ``| |end + 360| - |start + 360| |``
    (AMRISim's Stage model; only the width matters, the scan is symmetric about the heading)."""
    return abs(abs(end_deg + 360.0) - abs(start_deg + 360.0))


def laser_count(start_deg: float, end_deg: float, res_cdeg: int) -> int:
    """Readings per scan after a resolution command (hundredths of a degree):
    ``ceil(ceil(FOV) / res) + 1``; 0 for resolution 0. 180 deg at 100: 181; 90 at 50: 181."""
    res = abs(int(res_cdeg))
    if res == 0:
        return 0
    return math.ceil(math.ceil(laser_fov(start_deg, end_deg)) * 100 / res) + 1


def laser_bearings(start_deg: float, end_deg: float, res_cdeg: int, count: int) -> list[float]:
    """Bearing (deg, laser frame, CCW positive) of each of ``count`` readings, in the order
    sent: ``-FOV/2 + i * res``, reversed when ``end < start``. When the count does not follow
    from the resolution (the field of view changed after it), the readings span the field of
    view evenly, as the Stage model keeps the count and changes the spacing."""
    if count <= 0:
        return []
    fov = laser_fov(start_deg, end_deg)
    res = abs(int(res_cdeg)) / 100.0
    step = res if laser_count(start_deg, end_deg, res_cdeg) == count else fov / max(1, count - 1)
    out = [-fov / 2.0 + i * step for i in range(count)]
    return out[::-1] if end_deg < start_deg else out


def decode_simstat(body: bytes | bytearray | memoryview) -> dict[str, int]:
    """A 0x62 packet's data as ``{field: int}`` (the fixed 56-byte :data:`SimStat` layout).
    Raises :class:`ProtocolError` for any other length."""
    if len(body) != _SIMSTAT.size:
        raise ProtocolError(f"ARCOS SIMSTAT must hold {_SIMSTAT.size} data bytes, got {len(body)}")
    return dict(zip(_SIMSTAT_NAMES, _SIMSTAT.unpack(bytes(body)), strict=True))


def encode_simstat(fields: dict[str, Any]) -> bytes:
    """One framed 0x62 packet (same bytes as ``SimStat.build``); missing fields are 0."""
    values = [int(fields.get(name, 0)) for name in _SIMSTAT_NAMES]
    return frame(bytes((PacketType.SIM_STAT,)) + _SIMSTAT.pack(*values))


def decode_seto(payload: bytes | bytearray | memoryview) -> tuple[int, int, int]:
    """The odometry SETO sets, from its command payload (type byte + data), as AMRISim reads
    it: no data is (0, 0, 0); otherwise a type byte then up to three int16 (mm, mm, deg), the
    missing ones 0. So a SETO with an ordinary int argument sets x to its magnitude."""
    data = bytes(payload[1:])
    if not data:
        return 0, 0, 0
    padded = data[: _SETO.size].ljust(_SETO.size, b"\x00")
    _argtype, x, y, th = _SETO.unpack(padded)
    return x, y, th
