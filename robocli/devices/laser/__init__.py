"""Hokuyo laser scanners over SCIP 2.0 (URG-04LX, UTM-30LX, UST-10LX): :class:`Laser`.

Modules: :mod:`~robocli.devices.laser.client` (connecting, requests, scans, streaming,
closing), :mod:`~robocli.devices.laser.scan` (:class:`LaserInfo`, :class:`Scan`),
:mod:`~robocli.devices.laser.mounted` (a laser on a robot: :func:`scan_points` in the robot's
and the odometry frame, :class:`MountedLaser`) and
:mod:`~robocli.devices.laser.clock` (the sensor's 24-bit clock on the host's).
"""

from __future__ import annotations

from robocli.devices.laser.client import Laser, ScanListener
from robocli.devices.laser.clock import SensorClock
from robocli.devices.laser.mounted import MountedLaser, PlacedScan, scan_points
from robocli.devices.laser.scan import LaserInfo, Scan

__all__ = [
    "Laser", "LaserInfo", "MountedLaser", "PlacedScan", "Scan", "ScanListener", "SensorClock",
    "scan_points",
]  # fmt: skip
