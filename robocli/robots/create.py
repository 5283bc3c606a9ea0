"""The iRobot Create 2 as a robot, apart from its wire format (``robocli.protocols.create_oi``).

Geometry and limits from iRobot's Create 2 OI Specification and manual: wheels 72 mm across,
235 mm apart, 508.8 encoder counts per wheel turn, velocities -500..500 mm/s per wheel, a
round body about 340 mm across with a bumper over its front half. The body is described with
the Pioneer's :class:`~robocli.robots.pioneer.RobotParams`, so both robots share one physics
model in the simulator.
"""

from __future__ import annotations

import math

from robocli.robots.pioneer import RobotParams

__all__ = [
    "CREATE2",
    "HALF_TRACK_M",
    "MAX_WHEEL_SPEED",
    "TICKS_PER_REV",
    "WHEEL_DIAMETER_M",
    "ticks_per_m",
]

WHEEL_DIAMETER_M = 0.072
TRACK_M = 0.235  #: distance between the wheels
HALF_TRACK_M = TRACK_M / 2.0
TICKS_PER_REV = 508.8
MAX_WHEEL_SPEED = 0.5  #: m/s, each wheel (drive commands are clamped to +-500 mm/s)
MAX_RADIUS_M = 2.0  #: the largest turn radius drive (137) takes


def ticks_per_m() -> float:
    """Encoder counts per metre of wheel travel."""
    return TICKS_PER_REV / (math.pi * WHEEL_DIAMETER_M)


CREATE2 = RobotParams(
    "create2",
    dist_conv=1.0,
    vel_conv=1.0,
    diff_conv=1.0 / (HALF_TRACK_M * 1000.0),  # rad/s per mm/s of wheel-speed difference
    radius=0.17,
    width=0.34,
    length_front=0.17,
    length_rear=0.17,
    max_velocity=MAX_WHEEL_SPEED,
    max_rot_velocity=MAX_WHEEL_SPEED / HALF_TRACK_M,
    sonar=(),
    sonar_max_range=0.0,
)
