"""Simulated laser range finders: a vectorised ray caster and the scan geometry of MobileSim.

:func:`cast` is the sensor-independent part (any simulator can use it): ranges from a pose
along a set of bearings in a :class:`~robocli.sim.world.World`, all rays at once with NumPy.
:class:`LaserGeometry` is the configuration a client changes with the simulated-laser
commands (field of view, resolution in hundredths of a degree) and the rules of AMRISim's
Stage model (``docs/protocols/arcos-sim.md`` section 1):

* the field of view is ``| |end + 360| - |start + 360| |`` degrees and the scan is always
  symmetric about the laser's heading; ``end < start`` reverses the reading order;
* the number of readings is recomputed only when a resolution arrives:
  ``N = ceil(ceil(FOV) / res) + 1`` (180 deg at 1 deg: 181; 90 deg at 0.5 deg: 181); a later
  field-of-view change keeps ``N`` and changes the spacing; resolution 0 gives no readings;
* reading ``i`` is at ``start + i * res`` (what clients assume), so the last one lands on the
  end of the field of view.

:class:`LaserSpec` holds a model's fixed data (SICK LMS200 defaults for the Pioneers).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robocli.protocols.arcos import LASER_MAX_TOTAL, laser_bearings, laser_count, laser_fov
from robocli.sim.world import World

__all__ = ["LMS200", "LaserGeometry", "LaserSpec", "cast", "reflectance"]

FloatArray = npt.NDArray[np.float64]

log = logging.getLogger("robocli.sim.pioneer.server")


def cast(
    world: World,
    pose: tuple[float, float, float],
    angles: npt.ArrayLike,
    max_range: float,
    *,
    min_range: float = 0.0,
) -> FloatArray:
    """Ranges (m) from ``pose`` (x, y m; th rad) along ``angles`` (rad, relative to ``th``).

    One ray per angle, all walls at once. A ray that hits nothing within ``max_range`` gives
    ``inf`` (no return); a hit closer than ``min_range`` gives ``min_range``.
    """
    x, y, th = pose
    rel = np.asarray(angles, dtype=np.float64).ravel()
    n = len(rel)
    hit = world.cast(np.full(n, x), np.full(n, y), rel + th, math.inf)
    ranges: FloatArray = np.where(hit <= max_range, np.maximum(hit, min_range), math.inf)
    return ranges


def reflectance(
    reflectors: npt.ArrayLike,
    pose: tuple[float, float, float],
    angles: npt.ArrayLike,
    ranges: FloatArray,
    *,
    value: int = 32,
    max_range: float = 30.0,
    max_incidence: float = math.radians(45.0),
) -> npt.NDArray[np.int64]:
    """Reflectance of each reading: ``value`` where the ray's hit (``ranges``, from
    :func:`cast`) lies on one of the ``reflectors`` (segments x1, y1, x2, y2 in metres, lying
    on walls), within ``max_range`` and at most ``max_incidence`` from the segment's normal;
    0 elsewhere. The LMS200 rules of MobileSim/AMRISim give 32 (trace h) for a map's
    ``Reflector`` lines."""
    rel = np.asarray(angles, dtype=np.float64).ravel()
    out = np.zeros(len(rel), dtype=np.int64)
    segs = np.asarray(reflectors, dtype=np.float64).reshape(-1, 4)
    dx, dy = np.cos(rel + pose[2]), np.sin(rel + pose[2])
    for seg in segs:  # a map has few reflectors: one vectorised cast per segment
        r = cast(World.from_segments([seg.tolist()]), pose, rel, max_range)
        ex, ey = seg[2] - seg[0], seg[3] - seg[1]
        cos_inc = np.abs(dx * ey - dy * ex) / max(math.hypot(ex, ey), 1e-12)
        with np.errstate(invalid="ignore"):  # inf - inf where neither ray hit
            first = np.abs(r - ranges) < 1e-6  # the tape is the first thing the ray hits
        on = np.isfinite(r) & first & (cos_inc >= math.cos(max_incidence))
        out[on] = value
    return out


@dataclass(frozen=True)
class LaserSpec:
    """A laser model's fixed data: ranges (m), noise, mounting on the robot, defaults.

    ``no_return_mm``: what the wire carries for a ray without a hit (the model's maximum
    range in mm, exactly). ``noise``: uniform range noise +-``noise`` m, on hits only.
    ``mount``: x, y (m), th (rad) in the robot frame. ``fov_deg``/``res_cdeg``: the field of
    view and resolution (hundredths of a degree) before any client command.
    """

    name: str = "lms200"
    max_range: float = 32.767
    min_range: float = 0.0
    no_return_mm: int = 32767
    noise: float = 0.005
    mount: tuple[float, float, float] = (0.0, 0.0, 0.0)
    fov_deg: tuple[float, float] = (-90.0, 90.0)
    res_cdeg: int = 100


#: The p3dx's SICK LMS200 in MobileSim/AMRISim (``sicklms200``): 181 readings over 180 deg.
LMS200 = LaserSpec()


class LaserGeometry:
    """Field of view and resolution as the simulated-laser commands set them (see the module
    docstring; the rules are :func:`robocli.protocols.arcos.laser_count` and
    :func:`~robocli.protocols.arcos.laser_bearings`). Angles in degrees."""

    def __init__(self, spec: LaserSpec = LMS200) -> None:
        self.start, self.end = spec.fov_deg
        self.res_cdeg = spec.res_cdeg
        self.count = laser_count(self.start, self.end, self.res_cdeg)

    @property
    def fov(self) -> float:
        """Width of the field of view, degrees."""
        return laser_fov(self.start, self.end)

    def set_start(self, deg: float) -> None:
        """Start angle (OLD_LRF_CFG_START / SIM_LRF_SET_FOV_START); keeps the count."""
        self.start = float(deg)

    def set_end(self, deg: float) -> None:
        """End angle (OLD_LRF_CFG_END / SIM_LRF_SET_FOV_END); keeps the count."""
        self.end = float(deg)

    def set_resolution(self, cdeg: int) -> None:
        """Resolution in hundredths of a degree (sign ignored); recomputes the count, which
        is capped at :data:`~robocli.protocols.arcos.LASER_MAX_TOTAL` readings (a bound on
        the work one command can ask for: beyond it the spacing widens)."""
        self.res_cdeg = abs(int(cdeg))
        count = laser_count(self.start, self.end, self.res_cdeg)
        if count > LASER_MAX_TOTAL:
            log.warning("laser resolution %.2f deg gives %d readings: capped at %d",
                        self.res_cdeg / 100.0, count, LASER_MAX_TOTAL)  # fmt: skip
        self.count = min(count, LASER_MAX_TOTAL)

    def bearings(self) -> FloatArray:
        """Bearing of each reading (rad, laser frame, in the order sent)."""
        deg = laser_bearings(self.start, self.end, self.res_cdeg, self.count)
        out: FloatArray = np.radians(np.array(deg, dtype=np.float64))
        return out
