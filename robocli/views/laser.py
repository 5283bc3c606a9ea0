"""A Hokuyo laser as ``connect laser`` shows it: its identity in three lines, each scan in
one line or as JSON-ready SI data (ranges in m, None where the sensor sent an error code;
angles in rad, counter-clockwise, 0 ahead; ``t`` in Unix time)."""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

from robocli.io.jsonlines import rounded

if TYPE_CHECKING:
    from robocli.devices.laser import Laser, PlacedScan, Scan

__all__ = ["LASER_RESOLUTION", "identity_lines", "placed_json", "scan_json", "scan_line"]

#: JSON decimals by field: 1 mm ranges, angles to 1e-6 rad (a step is 4.4e-3 rad); points
#: placed on a robot to 0.1 mm.
LASER_RESOLUTION = {"t": 6, "received": 6, "ranges": 3, "angles": 6, "intensities": 0,
                    "points_robot": 4, "points_odom": 4}  # fmt: skip


def scan_json(laser: Laser, scan: Scan) -> dict[str, Any]:
    """One scan of ``laser`` as JSON-ready SI data, rounded to the sensor's resolution."""
    out = scan.as_dict()
    out["model"] = laser.info.model if laser.info else "?"
    return rounded(out, 6, LASER_RESOLUTION)  # type: ignore[no-any-return]


def placed_json(placed: PlacedScan) -> dict[str, Any]:
    """A scan placed on a robot (``connect pioneer --laser``) as JSON-ready SI data (see
    :meth:`PlacedScan.as_dict`), rounded to the sensor's resolution."""
    return rounded(placed.as_dict(), 6, LASER_RESOLUTION)  # type: ignore[no-any-return]


def identity_lines(laser: Laser) -> list[str]:
    """The model, serial and URL; firmware and protocol; range, steps, angles and speed."""
    info = laser.info
    assert info is not None
    return [
        f"{info.model} serial {info.serial} on {laser.url}",
        f"firmware  {info.vv.get('FIRM', '?')}   protocol {info.vv.get('PROT', '?')}"
        + ("  (switched from SCIP 1.1)" if laser.switched else ""),
        f"range     {info.dmin / 1000:.3f} .. {info.dmax / 1000:.3f} m   steps "
        f"{info.amin}..{info.amax} ({math.degrees(info.angle(info.amin)):.1f} .. "
        f"{math.degrees(info.angle(info.amax)):.1f} deg)   {info.rpm} rpm "
        f"({info.period * 1000:.0f} ms)",
    ]


def scan_line(scan: Scan) -> str:
    """One scan in one line: time, valid count, nearest range and its bearing, and the
    nearest range in each of 8 sectors (m, '-' where nothing valid)."""
    import numpy as np

    valid = ~np.isnan(scan.ranges)
    stamp = time.strftime("%H:%M:%S", time.localtime(scan.t)) + f".{int(scan.t * 1000) % 1000:03d}"
    if not valid.any():
        return f"{stamp}  {len(scan.ranges)} steps, no valid range"
    i = int(np.nanargmin(scan.ranges))
    sectors = []
    n = len(scan.ranges)
    for k in range(8):
        part = scan.ranges[k * n // 8 : (k + 1) * n // 8]
        ok = part[~np.isnan(part)]
        sectors.append(f"{ok.min():5.2f}" if ok.size else "    -")
    return (
        f"{stamp}  {int(valid.sum())}/{n} valid  nearest {scan.ranges[i]:.3f} m at "
        f"{math.degrees(scan.angles[i]):+6.1f} deg  sectors {' '.join(sectors)}"
    )
