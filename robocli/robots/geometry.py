"""Small geometry helpers shared by the devices and the simulators."""

from __future__ import annotations

import math
from dataclasses import dataclass


def wrap_pi(a: float) -> float:
    """The angle ``a`` (rad) wrapped into [-pi, pi)."""
    return (a + math.pi) % (2 * math.pi) - math.pi


@dataclass(frozen=True)
class Mount:
    """Where a sensor sits on a robot: ``x`` m forward, ``y`` m left, ``th`` rad
    counter-clockwise from forward, in the robot's frame (``base_link``); ``flipped``: mounted
    upside down (its angles run clockwise)."""

    x: float = 0.0
    y: float = 0.0
    th: float = 0.0
    flipped: bool = False

    def place(self, pose: tuple[float, float, float]) -> tuple[float, float, float]:
        """The sensor's pose (m, m, rad) in the frame where the robot is at ``pose``."""
        x, y, th = pose
        c, s = math.cos(th), math.sin(th)
        return x + c * self.x - s * self.y, y + s * self.x + c * self.y, wrap_pi(th + self.th)


__all__ = ["Mount", "wrap_pi"]
