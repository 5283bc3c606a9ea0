"""A Pioneer simulator's laser and status in SI units: scans reassembled from their packets,
SIMSTAT replies (no threads, no I/O; :class:`~robocli.devices.pioneer.Pioneer` feeds them).

MobileSim/AMRISim and the built-in simulator send one complete scan after every SIP, split
into packets of at most 32 readings (0x60 plain, 0x61 extended). :class:`ScanAssembler`
rebuilds scans from them the way the vendor SDK does (a scan starts with the packet whose
``first`` is 0 and ends with the one where ``first + n >= total``), but refuses what does not
fit: a packet out of order, a total that changes mid-scan or exceeds :data:`MAX_READINGS`, a
scan that is abandoned before its last packet. Those scans are dropped and counted.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass

from robocli.errors import ProtocolError
from robocli.protocols import arcos
from robocli.robots.geometry import wrap_pi

__all__ = [
    "MAX_READINGS",
    "GpsFix",
    "LaserScan",
    "LaserSettings",
    "ScanAssembler",
    "SimStatus",
    "parse_simstatus",
]

MAX_READINGS = arcos.LASER_MAX_TOTAL  #: largest scan accepted (0.05 deg over 360 deg: 7201)
DEFAULT_MAX_RANGE = 32.0  #: m: the vendor SDK's LMS2xx limit; longer readings are no return


@dataclass(frozen=True)
class LaserSettings:
    """What the client asked the simulator for (the angles of a scan are computed from it, as
    the vendor SDK does). Degrees and hundredths of a degree, as on the wire."""

    start_deg: int = -90
    end_deg: int = 90
    res_cdeg: int = 100
    max_range: float = DEFAULT_MAX_RANGE  #: m; readings beyond it are "no return"


@dataclass(frozen=True)
class LaserScan:
    """One complete laser scan.

    ``angles``: bearing of each reading, rad, in the robot frame (0 ahead, counter-clockwise
    positive), in the order sent. ``ranges``: metres; ``math.inf`` where the laser saw nothing
    (the wire's "no return" value, the model's maximum range, or anything beyond
    ``max_range``). ``reflectance``: per reading (extended 0x61 scans), else None. ``t``:
    monotonic time the scan's first packet arrived; ``pose``: the robot's odometric pose
    (m, m, rad) at that time (the latest SIP's), which is the pose the vendor SDK gives a scan.
    ``moved``: the simulator teleported the robot (SIM_SET_POSE) since the previous scan.
    """

    t: float
    angles: tuple[float, ...]
    ranges: tuple[float, ...]
    reflectance: tuple[int, ...] | None
    pose: tuple[float, float, float]
    moved: bool = False

    def __len__(self) -> int:
        return len(self.ranges)

    def nearest(self) -> tuple[float, float] | None:
        """``(range m, bearing rad)`` of the closest return, None if nothing was seen."""
        best = min(range(len(self.ranges)), key=self.ranges.__getitem__, default=None)
        if best is None or math.isinf(self.ranges[best]):
            return None
        return self.ranges[best], self.angles[best]

    def points(self) -> list[tuple[float, float]]:
        """The returns as (x, y) in the robot frame (m); no-return readings are left out."""
        return [
            (r * math.cos(a), r * math.sin(a))
            for r, a in zip(self.ranges, self.angles, strict=True)
            if math.isfinite(r)
        ]


class ScanAssembler:
    """Packets in, complete scans out (thread-safe; see the module docstring).

    ``count(name)`` is called with ``"laser_scans"`` for each scan returned and with
    ``"laser_dropped"`` for each scan given up (incomplete, out of order, too large, or with
    an undecodable packet).
    """

    def __init__(self, count: Callable[[str], None] = lambda name: None) -> None:
        self._count = count
        self._skip_total = -1  # the total of a refused scan whose packets are still coming
        self._lock = threading.Lock()
        self._parts: list[arcos.LaserPacket] = []
        self._got = 0
        self._t = 0.0
        self._pose = (0.0, 0.0, 0.0)

    def feed(
        self, ptype: int, body: bytes, t: float, pose: tuple[float, float, float],
        settings: LaserSettings,
    ) -> LaserScan | None:  # fmt: skip
        """One laser packet's data -> the completed scan, if this packet ends one.

        ``pose`` is the robot's pose now (kept if this packet starts a scan). Raises
        :class:`ProtocolError` for an undecodable packet (the scan is dropped first)."""
        with self._lock:
            try:
                pkt = arcos.decode_laser(ptype, body)
            except ProtocolError:
                self._drop()
                raise
            if pkt.first == 0:
                self._drop()  # a scan still open here never got its last packet
                self._skip_total = -1
                if not 0 < pkt.total <= MAX_READINGS:
                    self._skip_total = pkt.total
                    self._count("laser_dropped")
                    return None
                self._t, self._pose = t, pose
            elif not self._parts or pkt.first != self._got or pkt.total != self._parts[0].total:
                if self._parts:
                    self._drop()  # the scan being built lost a packet
                elif pkt.total != self._skip_total:
                    self._count("laser_dropped")  # the tail of a scan we did not see start
                self._skip_total = pkt.total
                return None
            self._parts.append(pkt)
            self._got += len(pkt.ranges)
            if not pkt.last:
                return None
            parts, self._parts, self._got = self._parts, [], 0
            if sum(len(p.ranges) for p in parts) != pkt.total:
                self._count("laser_dropped")
                return None
            self._count("laser_scans")
            return self._scan(parts, settings)

    def _drop(self) -> None:
        if self._parts:
            self._count("laser_dropped")
        self._parts, self._got = [], 0

    def _scan(self, parts: list[arcos.LaserPacket], settings: LaserSettings) -> LaserScan:
        total = parts[0].total
        s = settings
        deg = arcos.laser_bearings(s.start_deg, s.end_deg, s.res_cdeg, total)
        limit = round(s.max_range * 1000.0)
        ranges = tuple(
            r / 1000.0 if r <= limit and r != arcos.LASER_NO_RETURN_MM else math.inf
            for p in parts
            for r in p.ranges
        )
        refl = None
        if parts[0].reflectance is not None:
            refl = tuple(v for p in parts for v in (p.reflectance or ()))
        return LaserScan(
            t=self._t, angles=tuple(math.radians(d) for d in deg), ranges=ranges,
            reflectance=refl, pose=self._pose, moved=bool(parts[0].flags & arcos.SIM_LASER_MOVED),
        )  # fmt: skip


@dataclass(frozen=True)
class GpsFix:
    """A simulated GPS fix: degrees, metres; ``dop`` None inside a bad-GPS sector."""

    latitude: float
    longitude: float
    altitude: float
    dop: float | None


@dataclass(frozen=True)
class SimStatus:
    """A simulator's SIMSTAT reply (0x62) in SI units.

    ``true_pose``: where the robot really is in the simulated world (m, m, rad; the heading
    in [-pi, pi), which AMRISim sends unwrapped), unlike the odometry.
    ``sim_interval``/``real_interval``/``last_interval``: simulated seconds per step, the
    configured and the measured real seconds per step. ``gps``: with a
    georeferenced map, else None. ``odometry_error``: the fractional scale errors of the
    odometry (x, y displacement and rotation), None if the simulator does not report them.
    ``t``: monotonic receive time. ``fields``: the raw packet fields.
    """

    t: float
    true_pose: tuple[float, float, float]
    sim_interval: float
    real_interval: float
    last_interval: float
    gps: GpsFix | None
    odometry_error: tuple[float, float, float] | None
    fields: dict[str, int]


def parse_simstatus(body: bytes, t: float) -> SimStatus:
    """A 0x62 packet's data (the fixed 56-byte layout) as a :class:`SimStatus`. Raises
    :class:`ProtocolError` for any other length."""
    f = arcos.decode_simstat(body)
    gps = None
    if f["flags"] & arcos.SIMSTAT_FLAG_GEOREF:
        dop = f["gps_dop"]
        gps = GpsFix(f["latitude"] / 1e7, f["longitude"] / 1e7, f["altitude"] / 100.0,
                     dop / 100.0 if dop > 0 else None)  # fmt: skip
    odo_err = None
    if f["flags"] & arcos.SIMSTAT_FLAG_ODOM_ERROR:
        odo_err = (f["odom_error_x"] / 1e10, f["odom_error_y"] / 1e10,
                   f["odom_error_th"] / (math.degrees(1.0) * 1e7))  # fmt: skip
    return SimStatus(
        t=t, true_pose=(f["x"] / 1000.0, f["y"] / 1000.0, wrap_pi(math.radians(f["th"]))),
        sim_interval=f["sim_interval"] / 1000.0, real_interval=f["real_interval"] / 1000.0,
        last_interval=f["last_interval"] / 1000.0, gps=gps, odometry_error=odo_err, fields=f,
    )  # fmt: skip
