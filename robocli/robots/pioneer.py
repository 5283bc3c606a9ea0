"""Pioneer robot models: per-subtype conversion factors, body and sonar geometry.

What a Pioneer *is*, apart from its wire format: the values of AriaCoda's ``params/*.p``
files. Devices use them to turn ARCOS raw units into SI; the simulator uses them to be
the robot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from robocli.robots.geometry import Mount


@dataclass(frozen=True)
class SonarPose:
    x: float  #: m, forward
    y: float  #: m, left
    th: float  #: rad, CCW from forward


def _poses(rows: list[tuple[int, int, int]]) -> tuple[SonarPose, ...]:
    return tuple(SonarPose(x / 1000.0, y / 1000.0, math.radians(t)) for x, y, t in rows)


_P3DX_SONAR = _poses(
    [(69, 136, 90), (114, 119, 50), (148, 78, 30), (166, 27, 10), (166, -27, -10),
     (148, -78, -30), (114, -119, -50), (69, -136, -90), (-157, -136, -90), (-203, -119, -130),
     (-237, -78, -150), (-255, -27, -170), (-255, 27, 170), (-237, 78, 150), (-203, 119, 130),
     (-157, 136, 90)]
)  # fmt: skip
_P3AT_SONAR = _poses(
    [(147, 136, 90), (193, 119, 50), (227, 79, 30), (245, 27, 10), (245, -27, -10),
     (227, -79, -30), (193, -119, -50), (147, -136, -90), (-144, -136, -90), (-189, -119, -130),
     (-223, -79, -150), (-241, -27, -170), (-241, 27, 170), (-223, 79, 150), (-189, 119, 130),
     (-144, 136, 90)]
)  # fmt: skip
_AMIGO_SH_SONAR = _poses(
    [(70, 100, 90), (125, 75, 41), (144, 30, 15), (144, -30, -15), (120, -75, -41),
     (70, -100, -90), (-146, -58, -145), (-146, 58, 145)]
)  # fmt: skip
_AMIGO_SONAR = _poses(
    [(76, 100, 90), (125, 75, 41), (150, 30, 15), (150, -30, -15), (125, -75, -41),
     (76, -100, -90), (-140, -58, -145), (-140, 58, 145)]
)  # fmt: skip
_PEOPLEBOT_SONAR = _P3DX_SONAR + _poses(
    [(-20, 136, 90), (24, 119, 50), (58, 78, 30), (77, 27, 10), (77, -27, -10), (58, -78, -30),
     (24, -119, -50), (-20, -136, -90), (-191, -136, -90), (-237, -119, -130),
     (-271, -78, -150), (-290, -27, -170), (-290, 27, 170), (-271, 78, 150), (-237, 119, 130),
     (-191, 136, 90)]
)  # fmt: skip
_POWERBOT_SONAR = _poses(
    [(152, 278, 90), (200, 267, 65), (241, 238, 45), (274, 200, 35), (300, 153, 25),
     (320, 96, 15), (332, 33, 5), (0, 0, -180), (332, -33, -5), (320, -96, -15),
     (300, -153, -25), (274, -200, -35), (241, -238, -45), (200, -267, -65), (152, -278, -90),
     (0, 0, -180), (-298, -278, -90), (-347, -267, -115), (-388, -238, -135),
     (-420, -200, -145), (-447, -153, -155), (-467, -96, -165), (-478, -33, -175),
     (0, 0, -180), (-478, 33, 175), (-467, 96, 165), (-447, 153, 155), (-420, 200, 145),
     (-388, 238, 135), (-347, 267, 115), (-298, 278, 90)]
)  # fmt: skip


@dataclass(frozen=True)
class RobotParams:
    """Per-subtype conversion factors and geometry (values of AriaCoda's ``params/*.p``)."""

    subtype: str
    dist_conv: float  #: mm per position unit
    vel_conv: float  #: mm/s per wheel-velocity unit
    diff_conv: float  #: rad/s of rotation per mm/s of wheel-speed difference
    angle_conv: float = 2 * math.pi / 4096  #: rad per heading unit
    range_conv: float = 1.0  #: mm per sonar unit
    vel2_divisor: float = 20.0  #: mm/s per VEL2 byte unit
    radius: float = 0.25  #: m
    width: float = 0.425  #: m
    length_front: float = 0.210  #: m
    length_rear: float = 0.301  #: m
    max_velocity: float = 2.2  #: m/s, absolute
    max_rot_velocity: float = math.radians(500)  #: rad/s, absolute
    sonar: tuple[SonarPose, ...] = field(default=_P3DX_SONAR)
    sonar_max_range: float = 5.0  #: m (MobileSim's p3dx model)
    #: Where a laser scanner sits (``params/*.p`` LaserX, LaserY mm, LaserTh deg,
    #: LaserFlipped); the robot's centre where robocli does not know the model's values
    laser_mount: Mount = field(default=Mount())
    #: Drawn in robot models (:mod:`robocli.robots.urdf`): the P3-DX's wheels (195 mm, 47 mm
    #: wide) and body height (237 mm, its data sheet), used where robocli has no other values
    wheel_radius: float = 0.0975  #: m
    wheel_width: float = 0.047  #: m
    body_height: float = 0.237  #: m, the top plate above the floor

    @property
    def half_track(self) -> float:
        """Half the distance between the wheels (m), from ``diff_conv``: a rotation of
        ``w`` rad/s is a wheel-speed difference of ``2 * half_track * w``."""
        return 1.0 / (self.diff_conv * 1000.0)


#: The P3-DX's laser: ``p3dx.p`` gives LaserX 18, LaserY 0, LaserTh 0, not flipped.
_P3DX_LASER = Mount(0.018, 0.0, 0.0)


ROBOT_PARAMS: dict[str, RobotParams] = {
    p.subtype: p
    for p in (
        RobotParams("p3dx", dist_conv=0.485, vel_conv=1.0, diff_conv=0.0056,
                    laser_mount=_P3DX_LASER),
        RobotParams("p3dx-sh", dist_conv=1.0, vel_conv=1.0, diff_conv=0.0056,
                    laser_mount=_P3DX_LASER),
        RobotParams(
            "p3at", dist_conv=0.465, vel_conv=1.0, diff_conv=0.0034, radius=0.5, width=0.505,
            length_front=0.313, length_rear=0.313, max_velocity=1.2,
            max_rot_velocity=math.radians(300), sonar=_P3AT_SONAR,
        ),
        RobotParams(
            "p3at-sh", dist_conv=1.0, vel_conv=1.0, diff_conv=0.0034, radius=0.5, width=0.505,
            length_front=0.313, length_rear=0.313, max_velocity=1.2,
            max_rot_velocity=math.radians(300), sonar=_P3AT_SONAR,
        ),
        RobotParams(
            "amigo", dist_conv=0.5083, vel_conv=0.6154, diff_conv=0.011, radius=0.18,
            width=0.279, length_front=0.16, length_rear=0.17, max_velocity=1.0,
            max_rot_velocity=math.radians(300), sonar=_AMIGO_SONAR,
        ),
        RobotParams(
            "amigo-sh", dist_conv=1.0, vel_conv=1.0, diff_conv=0.011, radius=0.18,
            width=0.279, length_front=0.16, length_rear=0.17, max_velocity=1.0,
            max_rot_velocity=math.radians(300), sonar=_AMIGO_SH_SONAR,
        ),
        RobotParams(
            "peoplebot-sh", dist_conv=1.0, vel_conv=1.0, diff_conv=0.006, radius=0.34,
            width=0.425, length_front=0.2565, length_rear=0.2565, sonar=_PEOPLEBOT_SONAR,
        ),
        RobotParams(
            "powerbot", dist_conv=0.5813, vel_conv=1.0, diff_conv=0.00373, radius=0.55,
            width=0.68, length_front=0.369, length_rear=0.542, max_velocity=2.0,
            max_rot_velocity=math.radians(360), sonar=_POWERBOT_SONAR,
        ),
    )
}  # fmt: skip


__all__ = ["ROBOT_PARAMS", "Mount", "RobotParams", "SonarPose"]
