"""Small geometry helpers shared by the devices and the simulators."""

from __future__ import annotations

import math


def wrap_pi(a: float) -> float:
    """The angle ``a`` (rad) wrapped into [-pi, pi)."""
    return (a + math.pi) % (2 * math.pi) - math.pi


__all__ = ["wrap_pi"]
