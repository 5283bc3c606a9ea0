"""A Hokuyo on a Pioneer for ``connect pioneer --laser URL``: its placed scans as JSON;
connecting it is :func:`robocli.devices.laser.mounted.on_robot`."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from robocli.commands._common import rounded
from robocli.devices.laser.mounted import on_robot

if TYPE_CHECKING:
    from robocli.devices.laser import PlacedScan

__all__ = ["on_robot", "placed_json"]

#: JSON decimals by field: 1 mm ranges, angles to 1e-6 rad, points to 0.1 mm.
RESOLUTION = {"t": 6, "received": 6, "ranges": 3, "angles": 6, "intensities": 0,
              "points_robot": 4, "points_odom": 4}  # fmt: skip


def placed_json(placed: PlacedScan) -> dict[str, Any]:
    """A placed scan as JSON-ready SI data (see :meth:`PlacedScan.as_dict`)."""
    return rounded(placed.as_dict(), 6, RESOLUTION)  # type: ignore[no-any-return]
