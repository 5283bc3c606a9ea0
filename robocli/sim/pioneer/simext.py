"""The simulator-only part of the built-in Pioneer's ARCOS: simulated laser, SIMSTAT, teleports
and the cycle on which SETO takes effect (``docs/protocols/arcos-sim.md``).

:class:`SimExtensions` is used by :class:`~robocli.sim.pioneer.session.ArcosController` under its
lock: it contributes command handlers and the packets that go out around each SIP. Timing,
as AMRISim (which reads client input once per cycle, just after it sent the SIP batch):

* SETO, SIM_RESET and SIM_STAT 0/2 take effect so that the first SIP after the command still
  shows the old state and the second one the new state [trace j, i];
* SIM_STAT 1 is answered right after the next SIP [i];
* with SIM_STAT 2 a 0x62 goes out just before every SIP.

Deliberately faster than AMRISim: a laser enable or format switch takes effect on the next
SIP (AMRISim needs one more Stage update: its first scan comes with the third SIP).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from robocli.protocols.arcos import (
    SIM_LASER_MOVED,
    SIMSTAT_FLAG_GEOREF,
    SIMSTAT_FLAG_ODOM_ERROR,
    Command,
    decode_seto,
    encode_laser_scan,
    encode_simstat,
)
from robocli.sim.laser import LaserGeometry, LaserSpec, cast, reflectance
from robocli.sim.pioneer.model import PioneerModel

__all__ = ["Georef", "SimExtensions", "lat_lon"]

log = logging.getLogger("robocli.sim.pioneer.server")

#: A map's georeference: latitude, longitude (degrees) and altitude (m) of the world origin.
Georef = tuple[float, float, float]

_M_PER_DEG_LAT = 111_132.0  #: metres per degree of latitude (mean)
_M_PER_DEG_LON_EQ = 111_320.0  #: metres per degree of longitude at the equator
_I32 = 2**31 - 1

LASER_OFF, LASER_PLAIN, LASER_EXTENDED = 0, 1, 2


def lat_lon(georef: Georef, x: float, y: float) -> tuple[float, float]:
    """Latitude and longitude (degrees) of world point ``x`` (east), ``y`` (north) in metres,
    on a local flat-earth approximation around the origin (fine over a building)."""
    lat0, lon0, _ = georef
    lat = lat0 + y / _M_PER_DEG_LAT
    lon = lon0 + x / (_M_PER_DEG_LON_EQ * math.cos(math.radians(lat0)))
    return lat, lon


def _i32(v: float) -> int:
    return int(max(-_I32 - 1, min(_I32, v)))


def _int_arg(arg: Any) -> int:
    return arg if isinstance(arg, int) else 0


class SimExtensions:
    """Laser, SIMSTAT, SIM_SET_POSE/SIM_RESET and SETO for one simulated robot.

    ``laser``: the laser model (None: a robot without a laser, whose commands 35-38 keep
    their ARCOS meanings). ``georef``: the world origin's latitude, longitude, altitude for
    the SIMSTAT GPS fields (None: no georeference). ``reflectors``: segments (m) of walls
    that give the laser a reflectance (extended scans). ``sip_ms``/``period``: simulated ms
    and wall seconds per cycle. Not thread-safe: the controller holds its lock around every
    call.
    """

    def __init__(
        self, model: PioneerModel, *, laser: LaserSpec | None, georef: Georef | None,
        sip_ms: float, period: float, seed: int,
        reflectors: Sequence[Sequence[float]] = (),
    ) -> None:  # fmt: skip
        self.model, self.spec, self.georef = model, laser, georef
        self.reflectors = np.array(reflectors, dtype=np.float64).reshape(-1, 4)
        self.sip_ms, self.period = sip_ms, period
        self.geometry = LaserGeometry(laser) if laser is not None else None
        self.laser_mode = LASER_OFF
        self.simstat_mode = 0
        self.simstat_once = False
        self.moved = False  #: SIM_SET_POSE since the last scan (the 0x61 flag)
        self.scans = 0  #: complete scans sent
        self.enabled_at_sip = 0  #: SIPs sent when the laser was last switched on
        self.last_scan: tuple[float, ...] = ()  #: ranges (m, inf = no return) of the last scan
        self._deferred: list[tuple[int, Callable[[], None]]] = []
        self._sips = 0  # SIPs sent so far, as the controller counts them
        self._rng = np.random.default_rng(seed + 0x5EED)
        self._last_tick: float | None = None
        self._last_interval_ms = round(period * 1000.0)

    # ---------------------------------------------------------------- commands

    def handlers(self) -> dict[int, Callable[[Any, Any], None]]:
        """Command number -> handler(link, decoded arg), merged over the controller's."""
        out: dict[int, Callable[[Any, Any], None]] = {
            Command.SIM_SET_POSE: self._sim_set_pose,
            Command.SIM_RESET: lambda link, arg: self._defer(self._sim_reset),
            Command.SIM_STAT: self._sim_stat,
        }
        if self.geometry is not None:
            geo = self.geometry
            for enable, start, end, res in (
                (Command.ADSEL, Command.GRIPPERVAL, Command.GRIPREQUEST, Command.GYROCALCW),
                (Command.SIM_LRF_ENABLE, Command.SIM_LRF_FOV_START, Command.SIM_LRF_FOV_END,
                 Command.SIM_LRF_RES),
            ):  # fmt: skip
                out[enable] = self._laser_enable
                out[start] = lambda link, arg: geo.set_start(_int_arg(arg))
                out[end] = lambda link, arg: geo.set_end(_int_arg(arg))
                out[res] = lambda link, arg: geo.set_resolution(_int_arg(arg))
        return out

    def seto(self, payload: bytes) -> None:
        """SETO with its raw payload: no data = (0, 0, 0), else three int16 (mm, mm, deg)."""
        x, y, th = decode_seto(payload)
        self._defer(lambda: self.model.set_odometry(x / 1000.0, y / 1000.0, math.radians(th)))

    def _defer(self, action: Callable[[], None]) -> None:
        self._deferred.append((self._sips, action))

    def _laser_enable(self, link: Any, arg: Any) -> None:
        value = abs(_int_arg(arg))  # 0 off, 2 extended, any other value plain
        if value and not self.laser_mode:
            self.enabled_at_sip = self._sips
        self.laser_mode = LASER_OFF if value == 0 else LASER_EXTENDED if value == 2 else LASER_PLAIN

    def _sim_set_pose(self, link: Any, arg: Any) -> None:
        if isinstance(arg, tuple):
            x, y, th = arg
            self.model.teleport(x / 1000.0, y / 1000.0, math.radians(th))
            self.moved = True

    def _sim_reset(self) -> None:
        self.model.teleport(*self.model.start)
        self.model.reset_odometry()

    def _sim_stat(self, link: Any, arg: Any) -> None:
        mode = _int_arg(arg)  # no argument counts as 0 [trace i]
        if mode == 1:
            self.simstat_once = True
        elif mode in (0, 2):
            self._defer(lambda: setattr(self, "simstat_mode", mode))
        else:
            log.warning("SIM_STAT %d: not a mode (0 stop, 1 once, 2 every cycle); ignored", mode)

    # ---------------------------------------------------------------- session and cycle

    def open_session(self) -> None:
        """A session starts (or ends): laser off, SIMSTAT off, nothing pending."""
        self.laser_mode = LASER_OFF
        self.simstat_mode = 0
        self.simstat_once = self.moved = False
        self._deferred.clear()

    def before_sip(self, sips_sent: int, now: float) -> bytes:
        """Apply what arrived before the previous SIP; the 0x62 of SIM_STAT 2, if on."""
        if self._last_tick is not None:
            self._last_interval_ms = round((now - self._last_tick) * 1000.0)
        self._last_tick = now
        self._sips = sips_sent
        due = [a for n, a in self._deferred if n < sips_sent]
        self._deferred = [(n, a) for n, a in self._deferred if n >= sips_sent]
        for action in due:
            action()
        return self.simstat_packet() if self.simstat_mode == 2 else b""

    def after_sip(self, sips_sent: int) -> bytes:
        """The packets that follow a SIP: a requested 0x62, then one complete scan."""
        self._sips = sips_sent
        out = b""
        if self.simstat_once:
            self.simstat_once = False
            out += self.simstat_packet()
        if self.laser_mode and self.geometry is not None and self.geometry.count:
            out += self._scan()
        return out

    # ---------------------------------------------------------------- packets

    def _scan(self) -> bytes:
        spec, geo, r = self.spec, self.geometry, self.model
        assert spec is not None and geo is not None
        mx, my, mth = spec.mount
        c, s = math.cos(r.th), math.sin(r.th)
        pose = (r.x + c * mx - s * my, r.y + s * mx + c * my, r.th + mth)
        bearings = geo.bearings()
        ranges = cast(r.world, pose, bearings, spec.max_range, min_range=spec.min_range)
        extended = self.laser_mode == LASER_EXTENDED
        refl = None
        if extended and len(self.reflectors):
            refl = reflectance(self.reflectors, pose, bearings, ranges).tolist()
        hits = np.isfinite(ranges)
        if spec.noise > 0:
            noise = self._rng.uniform(-spec.noise, spec.noise, len(ranges))
            ranges = np.where(hits, np.maximum(ranges + noise, spec.min_range), ranges)
        mm = np.where(hits, np.round(np.where(hits, ranges, 0.0) * 1000.0), spec.no_return_mm)
        self.last_scan = tuple(float(v) for v in ranges)
        self.scans += 1
        flags = SIM_LASER_MOVED if self.moved else 0
        self.moved = False
        ox, oy, oth = r.odom
        odom = (round(ox * 1000.0), round(oy * 1000.0), round(math.degrees(oth)))
        return encode_laser_scan(mm.astype(int).tolist(), extended=extended, pose=odom,
                                 flags=flags, reflectance=refl)  # fmt: skip

    def simstat_packet(self) -> bytes:
        """One 0x62: intervals, true pose, GPS (with a georeference), odometry error."""
        r = self.model
        fields: dict[str, int] = {
            "flags": SIMSTAT_FLAG_ODOM_ERROR,
            "sim_interval": round(self.sip_ms),
            "real_interval": round(self.period * 1000.0),
            "last_interval": max(0, min(0xFFFF, self._last_interval_ms)),
            "x": _i32(math.trunc(r.x * 1000.0)),
            "y": _i32(math.trunc(r.y * 1000.0)),
            "th": round(math.degrees(r.th)),
            "gps_dop": -1,
        }
        if self.georef is not None:
            lat, lon = lat_lon(self.georef, r.x, r.y)
            fields.update(
                flags=SIMSTAT_FLAG_ODOM_ERROR | SIMSTAT_FLAG_GEOREF,
                latitude=_i32(round(lat * 1e7)), longitude=_i32(round(lon * 1e7)),
                altitude=_i32(round(self.georef[2] * 100.0)), gps_dop=100,
            )  # fmt: skip
        ex, eth = r.odom_error
        fields.update(
            odom_error_x=_i32(round(ex * 1e10)), odom_error_y=_i32(round(ex * 1e10)),
            odom_error_th=_i32(round(eth * math.degrees(1.0) * 1e7)),
        )  # fmt: skip
        return encode_simstat(fields)
