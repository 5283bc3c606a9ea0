"""The Pioneer's body in the simulator: unicycle physics, odometry, collisions, battery, sonar.

No protocol and no sockets: :class:`PioneerModel` takes commands in SI units and is stepped by
the simulator's ticker; ``robocli.sim.pioneer.session`` turns ARCOS commands into calls on it and
its state into packets. Robot data (``RobotParams``) comes from ``robocli.robots.pioneer``;
the walls it drives among and its sonar's ray casting come from :class:`~robocli.sim.world.World`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robocli.protocols.arcos import BUMPERS_FRONT_MASK, BUMPERS_REAR_MASK, STALL_LEFT, STALL_RIGHT
from robocli.robots.geometry import wrap_pi
from robocli.robots.pioneer import RobotParams
from robocli.sim.world import World

__all__ = ["Limits", "PioneerModel", "Pose", "clamp"]

Pose = tuple[float, float, float]

TICKS_PER_MM = 128  #: encoder ticks per mm of wheel travel (reported in CONFIG)
BATTERY_FULL_V = 13.0
BATTERY_EMPTY_V = 11.0
DRAIN_V_PER_M = 1.0e-4  #: battery drop per metre of wheel travel (both wheels summed)
DRAIN_V_PER_S = 1.0e-6  #: idle drain
ESTOP_DECEL = 2.0  #: m/s^2, ESTOP's "maximum deceleration"
ESTOP_ROT_DECEL = math.radians(500.0)
CONTACT_EPS = 0.005  #: m: a wall this close to the body presses its bumper
SONAR_CONE = math.radians(30.0)
SONAR_RAYS = 3
SONAR_MIN_RANGE = 0.1
NUM_BUMPERS = 5  #: per bumper ring (P3-DX: 5 front, 5 rear)


def clamp(v: float, lo: float, hi: float) -> float:
    """``v`` limited to ``lo..hi``."""
    return lo if v < lo else hi if v > hi else v


def _approach(cur: float, goal: float, accel: float, decel: float, dt: float) -> float:
    """Move ``cur`` toward ``goal``: ``accel`` when speeding up in the same direction."""
    speeding_up = abs(goal) > abs(cur) and (cur == 0.0 or (cur > 0) == (goal > 0))
    step = (accel if speeding_up else decel) * dt
    if abs(goal - cur) <= step:
        return goal
    return cur + math.copysign(step, goal - cur)


@dataclass
class Limits:
    """Per-session operating parameters (MobileSim's defaults), SI units.

    MobileSim's own ``trans_vel_max`` default is 3.0 m/s, above the p3dx's top speed (2.2),
    so the vendor SDK warns twice on every connect; :meth:`for_robot` keeps it within the top.
    """

    trans_vel_max: float = 3.0
    trans_accel: float = 0.3
    trans_decel: float = 0.3
    rot_vel_max: float = math.radians(150.0)
    rot_accel: float = math.radians(100.0)
    rot_decel: float = math.radians(100.0)

    @classmethod
    def for_robot(cls, params: RobotParams) -> Limits:
        """The defaults, the maximum velocities capped at the robot's top speeds (CONFIG's
        ``transvel_top``/``rotvel_top``)."""
        lim = cls()
        lim.trans_vel_max = min(lim.trans_vel_max, params.max_velocity)
        lim.rot_vel_max = min(lim.rot_vel_max, params.max_rot_velocity)
        return lim


class PioneerModel:
    """Unicycle with acceleration limits, collision against the world, odometry, battery.

    Not thread-safe: the simulator holds its lock around every call.
    """

    def __init__(
        self, params: RobotParams, world: World, start: Pose, noise: float, seed: int
    ) -> None:
        self.params = params
        self.world = world
        self.start = start
        self.noise = noise
        self.rng = np.random.default_rng(seed)
        self.half_track = params.half_track  # m: w = (r - l) / (2 * half_track)
        self.sensors = np.array([(s.x, s.y, s.th) for s in params.sonar], dtype=np.float64)
        self.limits = Limits.for_robot(self.params)
        self.x, self.y, self.th = start
        self.odom = [0.0, 0.0, 0.0]
        self.odom_error = (0.0, 0.0)  #: last relative odometry error drawn (distance, rotation)
        self.v = self.w = 0.0
        self.v_goal = self.w_goal = 0.0
        self.trans_mode = "vel"  # "vel" | "move"
        self.rot_mode = "vel"  # "vel" | "head"
        self.v_set = self.w_set = 0.0
        self.move_left = 0.0
        self.head_set = 0.0
        self.motors = False
        self.estop = False
        self.bump_stall = 0
        self.stall_bits = 0
        self.bumper_bits = 0
        self.wheel_travel = [0.0, 0.0]
        self.battery_v = BATTERY_FULL_V
        self.battery_override: float | None = None
        self.sim_time = 0.0
        self.sonar = np.full(len(self.sensors), params.sonar_max_range)
        self.update_sonar()

    # ---------------------------------------------------------------- commands (SI)

    def halt(self) -> None:
        """Both set-points to zero (normal deceleration)."""
        self.trans_mode, self.rot_mode = "vel", "vel"
        self.v_set = self.w_set = 0.0

    def set_motors(self, on: bool) -> None:
        """Motors on or off; off stops the robot at once, either way clears an ESTOP."""
        if on and self.motors:
            return  # ENABLE 1 while enabled changes nothing (and must not stop the robot)
        self.halt()
        self.motors = on
        self.estop = False
        if not on:
            self.v = self.w = 0.0

    def set_trans(self, v: float) -> None:
        """Translational velocity set-point (m/s)."""
        self.trans_mode, self.v_set = "vel", v

    def set_rot(self, w: float) -> None:
        """Rotational velocity set-point (rad/s)."""
        self.rot_mode, self.w_set = "vel", w

    def move(self, dist: float) -> None:
        """Drive ``dist`` metres (negative: backwards) and stop."""
        self.trans_mode, self.move_left = "move", dist

    def head(self, th_odom: float) -> None:
        """Turn to heading ``th_odom`` (rad, odometry frame)."""
        self.rot_mode, self.head_set = "head", wrap_pi(th_odom)

    def wheels(self, left: float, right: float) -> None:
        """Wheel velocity set-points (m/s)."""
        self.set_trans((left + right) / 2.0)
        self.set_rot((right - left) / (2.0 * self.half_track))

    def emergency_stop(self) -> None:
        """Stop at the maximum deceleration."""
        self.halt()
        self.estop = self.v != 0.0 or self.w != 0.0

    def reset_odometry(self) -> None:
        """Odometry back to (0, 0, 0); a heading goal follows it."""
        self.set_odometry(0.0, 0.0, 0.0)

    def set_odometry(self, x: float, y: float, th: float) -> None:
        """Odometry set to (m, m, rad) (SETO); a heading goal becomes the new heading."""
        self.odom = [x, y, wrap_pi(th)]
        if self.rot_mode == "head":
            self.head_set = self.odom[2]

    def teleport(self, x: float, y: float, th: float) -> None:
        """Move the true pose (m, m, rad); odometry is unchanged."""
        self.x, self.y, self.th = x, y, wrap_pi(th)
        self.update_sonar()

    def reset_session(self) -> None:
        """State at OPEN and after a session: stopped, motors off, defaults, odometry zero."""
        self.set_motors(False)
        self.limits = Limits.for_robot(self.params)
        self.bump_stall = 0
        self.reset_odometry()
        self.wheel_travel = [0.0, 0.0]

    # ---------------------------------------------------------------- readings

    @property
    def volts(self) -> float:
        """Battery voltage (V), or the BATTEST override."""
        return self.battery_v if self.battery_override is None else self.battery_override

    @property
    def state_of_charge(self) -> float:
        """Battery state of charge, percent."""
        frac = (self.volts - BATTERY_EMPTY_V) / (BATTERY_FULL_V - BATTERY_EMPTY_V)
        return clamp(100.0 * frac, 0.0, 100.0)

    def wheel_speeds(self) -> tuple[float, float]:
        """(left, right) m/s."""
        d = self.w * self.half_track
        return self.v - d, self.v + d

    def encoder_ticks(self) -> tuple[int, int]:
        """(left, right) wheel travel in encoder ticks, as signed 32-bit counters."""

        def ticks(m: float) -> int:
            return ((round(m * 1000.0 * TICKS_PER_MM) + 2**31) % 2**32) - 2**31

        return ticks(self.wheel_travel[0]), ticks(self.wheel_travel[1])

    def update_sonar(self) -> None:
        """Cast the sonar cones from the current pose."""
        self.sonar = self.world.sonar(
            (self.x, self.y, self.th),
            self.sensors,
            cone=SONAR_CONE,
            rays=SONAR_RAYS,
            min_range=SONAR_MIN_RANGE,
            max_range=self.params.sonar_max_range,
        )

    # ---------------------------------------------------------------- dynamics

    def step(self, dt: float) -> None:
        """Advance ``dt`` simulated seconds."""
        self.sim_time += dt
        if self.motors:
            self.v_goal, self.w_goal = self._trans_goal(dt), self._rot_goal(dt)
            lim = self.limits
            decel, rdecel = (
                (ESTOP_DECEL, ESTOP_ROT_DECEL) if self.estop else (lim.trans_decel, lim.rot_decel)
            )
            self.v = _approach(self.v, self.v_goal, lim.trans_accel, decel, dt)
            self.w = _approach(self.w, self.w_goal, lim.rot_accel, rdecel, dt)
            self.v = clamp(self.v, -self.params.max_velocity, self.params.max_velocity)
            wmax = self.params.max_rot_velocity
            self.w = clamp(self.w, -wmax, wmax)
        else:
            self.v_goal = self.w_goal = self.v = self.w = 0.0
        if self.estop and self.v == 0.0 and self.w == 0.0:
            self.estop = False
        self._integrate(dt)
        self.update_sonar()

    def _trans_goal(self, dt: float) -> float:
        vmax = min(self.limits.trans_vel_max, self.params.max_velocity)
        if self.trans_mode == "move":
            left = self.move_left
            if abs(left) < 0.0005:
                self.set_trans(0.0)
                return 0.0
            mag = min(vmax, math.sqrt(2.0 * self.limits.trans_decel * abs(left)), abs(left) / dt)
            return math.copysign(mag, left)
        return clamp(self.v_set, -vmax, vmax)

    def _rot_goal(self, dt: float) -> float:
        wmax = min(self.limits.rot_vel_max, self.params.max_rot_velocity)
        if self.rot_mode == "head":
            err = wrap_pi(self.head_set - self.odom[2])
            if abs(err) < math.radians(0.05):
                return 0.0
            mag = min(wmax, math.sqrt(2.0 * self.limits.rot_decel * abs(err)), abs(err) / dt)
            return math.copysign(mag, err)
        return clamp(self.w_set, -wmax, wmax)

    def _integrate(self, dt: float) -> None:
        ds, dth = self.v * dt, self.w * dt
        self.stall_bits = 0
        if ds != 0.0:
            frac = self._free_fraction(ds, dth)
            if frac < 1.0:
                ds, dth = ds * frac, dth * frac
                self._stall(front=self.v > 0)
        mid = self.th + dth / 2.0
        self.x += ds * math.cos(mid)
        self.y += ds * math.sin(mid)
        self.th = wrap_pi(self.th + dth)
        self._odometry(ds, dth)
        self.bumper_bits = self._contact_bumpers()
        travel = abs(ds - dth * self.half_track) + abs(ds + dth * self.half_track)
        self.battery_v = max(
            BATTERY_EMPTY_V - 1.0, self.battery_v - DRAIN_V_PER_M * travel - DRAIN_V_PER_S * dt
        )

    def _odometry(self, ds: float, dth: float) -> None:
        if self.noise > 0.0 and (ds or dth):
            self.odom_error = (
                self.noise * float(self.rng.standard_normal()),
                self.noise * float(self.rng.standard_normal()),
            )
            ds *= 1.0 + self.odom_error[0]
            dth *= 1.0 + self.odom_error[1]
        ox, oy, oth = self.odom
        mid = oth + dth / 2.0
        self.odom = [ox + ds * math.cos(mid), oy + ds * math.sin(mid), wrap_pi(oth + dth)]
        self.wheel_travel[0] += ds - dth * self.half_track
        self.wheel_travel[1] += ds + dth * self.half_track
        if self.trans_mode == "move":
            self.move_left -= ds

    def _stall(self, *, front: bool) -> None:
        self.stall_bits = STALL_LEFT | STALL_RIGHT
        self.v = self.w = 0.0
        if self.bump_stall & (1 if front else 2):
            self.halt()

    def _ok(self, ds: float, dth: float, before: float) -> bool:
        mid = self.th + dth / 2.0
        d = self.world.clearance(self.x + ds * math.cos(mid), self.y + ds * math.sin(mid))
        return d >= self.params.radius or d >= before

    def _free_fraction(self, ds: float, dth: float) -> float:
        """Largest fraction of the step that keeps the body out of the walls (1.0 = all)."""
        before = self.world.clearance(self.x, self.y)
        if math.isinf(before):
            return 1.0
        n = max(1, math.ceil(abs(ds) / (self.params.radius / 2.0)))
        lo = 0.0
        for k in range(1, n + 1):
            hi = k / n
            if not self._ok(ds * hi, dth * hi, before):
                for _ in range(12):
                    mid = (lo + hi) / 2.0
                    lo, hi = (mid, hi) if self._ok(ds * mid, dth * mid, before) else (lo, mid)
                return lo
            lo = hi
        return 1.0

    def _contact_bumpers(self) -> int:
        d, px, py = self.world.nearest(self.x, self.y)
        if d > self.params.radius + CONTACT_EPS:
            return 0
        a = wrap_pi(math.atan2(py - self.y, px - self.x) - self.th)
        front = abs(a) <= math.pi / 2
        if not front:
            a = wrap_pi(a - math.pi)
        i = int(clamp((math.pi / 2 - a) / (math.pi / NUM_BUMPERS), 0, NUM_BUMPERS - 1))
        bit = 1 << (i + 1)  # bumper 0 = leftmost seen from its ring's side
        return (bit << 8) & BUMPERS_FRONT_MASK if front else bit & BUMPERS_REAR_MASK
