"""The Create 2's body in the simulator: the Pioneer's physics with the Create's geometry.

:class:`CreateBody` drives a :class:`~robocli.sim.pioneer.model.PioneerModel` (unicycle,
acceleration limits, collisions against the same :class:`~robocli.sim.world.World`,
odometry, battery) built with :data:`robocli.robots.create.CREATE2`, and adds what the
Create's sensors read: its bumper (left/right, front half of the body), wheel drops and
cliffs (set from outside: a robot picked up, a stair), distance and angle since the last
read, encoder counts, the battery in the OI's units. No protocol, no sockets; the controller
holds its lock around every call.
"""

from __future__ import annotations

import math

from robocli.robots.create import CREATE2, HALF_TRACK_M, MAX_RADIUS_M, MAX_WHEEL_SPEED, ticks_per_m
from robocli.sim.pioneer.model import Limits, PioneerModel, Pose, clamp
from robocli.sim.world import World

__all__ = ["BUMP_LEFT", "BUMP_RIGHT", "DROP_LEFT", "DROP_RIGHT", "CreateBody"]

BUMP_RIGHT, BUMP_LEFT, DROP_RIGHT, DROP_LEFT = 1, 2, 4, 8  #: packet 7's bits
BUMP_CENTRE = math.radians(10.0)  #: a wall this close to straight ahead presses both sides
ACCEL = 1.0  #: m/s^2 (the Create reaches its set speed within a fraction of a second)
CAPACITY_MAH = 2696  #: a full battery (packet 26)
VOLTS_EMPTY, VOLTS_FULL = 13.0, 16.0  #: what packet 22 shows at 0 % and 100 %


def wheel_setpoints(velocity: int, radius: int) -> tuple[float, float]:
    """(left, right) wheel speeds (m/s) of drive (137): ``velocity`` mm/s of the centre,
    ``radius`` mm (positive: turn left); -32768 or 32767 straight, -1/1 in place."""
    v = clamp(velocity, -500, 500) / 1000.0
    if radius in (-32768, 32767) or radius == 0:
        return v, v
    if radius in (-1, 1):
        return -v * radius, v * radius
    r = clamp(radius, -MAX_RADIUS_M * 1000, MAX_RADIUS_M * 1000) / 1000.0
    left, right = v * (r - HALF_TRACK_M) / r, v * (r + HALF_TRACK_M) / r
    top = max(abs(left), abs(right))
    if top > MAX_WHEEL_SPEED:  # the outer wheel at its limit, the turn's shape kept
        left, right = left * MAX_WHEEL_SPEED / top, right * MAX_WHEEL_SPEED / top
    return left, right


class CreateBody:
    """A Create 2 in a world. All units SI unless a name says otherwise."""

    def __init__(self, world: World, start: Pose, noise: float = 0.0, seed: int = 0) -> None:
        self.model = PioneerModel(CREATE2, world, start, noise, seed)
        wmax = MAX_WHEEL_SPEED / HALF_TRACK_M
        self.model.limits = Limits(MAX_WHEEL_SPEED, ACCEL, ACCEL, wmax,
                                   ACCEL / HALF_TRACK_M, ACCEL / HALF_TRACK_M)  # fmt: skip
        self.drops = 0  #: DROP_LEFT | DROP_RIGHT while a wheel hangs
        self.cliffs = (False, False, False, False)  #: left, front left, front right, right
        self.set_left = self.set_right = 0.0  #: the wheel speeds last asked (m/s)
        self._told_mm = 0.0  # distance (mm) already reported by packet 19
        self._told_deg = 0.0  # angle (deg) already reported by packet 20

    # ---------------------------------------------------------------- commands

    def wheels(self, left: float, right: float) -> None:
        """Wheel speed set-points (m/s, each clamped to the Create's 0.5)."""
        self.set_left = clamp(left, -MAX_WHEEL_SPEED, MAX_WHEEL_SPEED)
        self.set_right = clamp(right, -MAX_WHEEL_SPEED, MAX_WHEEL_SPEED)
        self.model.wheels(self.set_left, self.set_right)

    def enable(self, on: bool) -> None:
        """Wheels under command (safe, full) or not (off, passive: stopped at once)."""
        self.model.set_motors(on)
        self.set_left = self.set_right = 0.0

    def step(self, dt: float) -> None:
        """Advance ``dt`` simulated seconds (a hanging robot's wheels turn freely: it does
        not move)."""
        if self.drops == DROP_LEFT | DROP_RIGHT:
            self.model.sim_time += dt
            return
        self.model.step(dt)

    # ---------------------------------------------------------------- readings

    def bumps(self) -> int:
        """Packet 7's bump bits from the wall the body touches (front half only)."""
        a = self.model.contact_bearing()
        if a is None or abs(a) > math.pi / 2:
            return 0
        if abs(a) <= BUMP_CENTRE:
            return BUMP_LEFT | BUMP_RIGHT
        return BUMP_LEFT if a > 0 else BUMP_RIGHT

    def travel_mm(self) -> tuple[float, float]:
        """(distance, angle) the odometry measured since the start: mm of the centre and
        degrees counter-clockwise."""
        left, right = self.model.wheel_travel
        return (left + right) * 500.0, math.degrees((right - left) / (2.0 * HALF_TRACK_M))

    def take_distance(self) -> int:
        """Packet 19: mm since the last read (what is not reported yet carries over, so the
        sum of the reads follows the odometry within a millimetre)."""
        dist, _ = self.travel_mm()
        d = int(clamp(round(dist - self._told_mm), -32768, 32767))
        self._told_mm += d
        return d

    def take_angle(self) -> int:
        """Packet 20: degrees since the last read (carries over as :meth:`take_distance`)."""
        _, ang = self.travel_mm()
        d = int(clamp(round(ang - self._told_deg), -32768, 32767))
        self._told_deg += d
        return d

    def encoders(self) -> tuple[int, int]:
        """Packets 43, 44: (left, right) encoder counts, signed 16-bit, rolling over."""

        def counts(m: float) -> int:
            return ((round(m * ticks_per_m()) + 0x8000) % 0x10000) - 0x8000

        return counts(self.model.wheel_travel[0]), counts(self.model.wheel_travel[1])

    def battery(self) -> tuple[int, int, int, int]:
        """(mV, mA, mAh charge, mAh capacity) of packets 22, 23, 25, 26 (driving draws more)."""
        soc = self.model.state_of_charge / 100.0
        left, right = self.model.wheel_speeds()
        milliamps = -round(150 + 1000 * (abs(left) + abs(right)))
        volts = VOLTS_EMPTY + soc * (VOLTS_FULL - VOLTS_EMPTY)
        return round(volts * 1000), milliamps, round(soc * CAPACITY_MAH), CAPACITY_MAH
