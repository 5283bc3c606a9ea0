"""Wander: explore a room, turning away from whatever the sonar ring and the laser see.

The behaviours of ARIA's wander, as its manual describes them (written anew here from that
description, not from its code), by priority; the first that has something to say drives:

1. recover: a bumper pressed or a wheel stalled: back off (forward after a rear bump), then
   turn on the spot for a moment;
2. avoid front: something in the robot's path (a corridor as wide as the robot) closer than
   ``avoid``: stop and turn on the spot toward the more open side, and keep turning that
   way until the path is clear for ``clear`` metres and a bit more (the bit drawn at
   random, so that the robot does not retrace one loop; asked a little less each step, so
   that a corner ends the turn too), never dithering between sides: it heads back into the
   room rather than along the wall;
3. avoid side: something beside the robot closer than ``side``: steer away while driving;
4. cruise: forward at up to ``max_v``, slower as the free path ahead shortens, with a slow
   random meander.

Obstacles are the sonar echoes (placed by each transducer's pose on the robot) and, when the
robot has one, the laser's returns. The random draws come from ``seed``: a run on the
simulator is repeatable.

    python examples/wander.py tcp://127.0.0.1:8101 --seconds 60
    python examples/wander.py sim://                    # the built-in simulator, in-process
"""

from __future__ import annotations

import argparse
import math
import random
from dataclasses import dataclass, field

from robocli import Pioneer
from robocli.robots.pioneer import RobotParams

Point = tuple[float, float]


@dataclass
class WanderParams:
    max_v: float = 0.4  #: m/s, cruising
    turn_w: float = 0.9  #: rad/s, turning on the spot
    avoid: float = 0.55  #: m of free path ahead under which the robot stops and turns
    clear: float = 2.5  #: m of free path ahead the turn goes on for (plus up to ``extra``)
    extra: float = 4.0  #: m, the most drawn at random on top of ``clear``
    settle: float = 0.05  #: m the turn asks less for each SIP it lasts (it ends in a corner)
    slow: float = 1.6  #: m of free path ahead under which it slows down
    side: float = 0.35  #: m between the body's side and an obstacle it steers away from
    side_gain: float = 0.25  #: rad/s per 1/m of side closeness
    margin: float = 0.08  #: m added to each side of the robot's path
    meander: float = 0.25  #: rad/s, the largest random drift while cruising
    meander_sips: int = 30  #: SIPs between two drift draws
    backoff_sips: int = 6  #: SIPs backing off after a hit, then as many turning
    seed: int = 1


@dataclass
class WanderResult:
    distance: float  #: m travelled (odometry path length)
    bumps: int  #: bumper or stall events
    turns: int = 0  #: turns on the spot away from an obstacle ahead
    path: list[tuple[float, float]] = field(default_factory=list)  #: odometry (x, y) per SIP


def obstacles(ranges: tuple[float, ...], robot: RobotParams,
              laser: list[Point] | None = None) -> list[Point]:  # fmt: skip
    """Obstacle points (x forward, y left, m, robot frame): each sonar echo (no reading and
    the sonar's maximum range are no echo), then the laser's returns."""
    points = []
    for rng, pose in zip(ranges, robot.sonar, strict=False):
        if math.isfinite(rng) and 0.0 < rng < robot.sonar_max_range - 0.01:
            points.append((pose.x + rng * math.cos(pose.th), pose.y + rng * math.sin(pose.th)))
    return points + list(laser or ())


@dataclass
class View:
    """What the obstacles leave the robot: the free path ahead (m from its front), the
    room beside it (m from its sides) and how open each side's quarter is (m)."""

    ahead: float
    left: float
    right: float
    open_left: float
    open_right: float


def look(points: list[Point], robot: RobotParams, margin: float, far: float = 4.0) -> View:
    """The :class:`View` of ``points``; a side's openness is the mean distance (each at most
    ``far``) of what lies in its quarter, ahead of the robot's flank (``far``: nothing)."""
    half = robot.width / 2
    ahead = left = right = math.inf
    sides: tuple[list[float], list[float]] = ([], [])
    for x, y in points:
        if x > 0.0 and abs(y) < half + margin:
            ahead = min(ahead, x - robot.length_front)
        if -robot.length_rear < x < robot.length_front + 0.3:
            if y > 0:
                left = min(left, y - half)
            else:
                right = min(right, -y - half)
        bearing = math.atan2(y, x)
        if math.radians(10) < abs(bearing) < math.radians(100):
            sides[bearing < 0].append(min(math.hypot(x, y), far))
    open_left, open_right = (sum(d) / len(d) if d else far for d in sides)
    return View(max(ahead, 0.0), max(left, 0.0), max(right, 0.0), open_left, open_right)


class Wanderer:
    """The behaviours above as a state machine: :meth:`step` takes one SIP's view and
    says ``(v, w)``."""

    def __init__(self, params: WanderParams) -> None:
        self.p = params
        self.rng = random.Random(params.seed)
        self.turning = 0.0  #: the turn's direction (+1 left, -1 right), 0 when not turning
        self.until = 0.0  #: m of free path ahead that ends the turn
        self.recover = 0  #: SIPs of recovery left
        self.recover_v = 0.0
        self.drift = 0.0
        self.sips = 0
        self.hits = self.turns = 0

    def hit(self, rear: bool) -> None:
        """A bumper or a stall: back off (forward from a rear bump), then turn."""
        if self.recover == 0:
            self.hits += 1
        self.recover = 2 * self.p.backoff_sips
        self.recover_v = 0.12 if rear else -0.12
        self.turning = self.rng.choice((-1.0, 1.0))
        self.until = self.p.clear + self.rng.uniform(0.0, self.p.extra)

    def step(self, view: View) -> tuple[float, float]:
        p = self.p
        self.sips += 1
        if self.recover:
            self.recover -= 1
            if self.recover >= p.backoff_sips:
                return self.recover_v, 0.0
            return 0.0, self.turning * p.turn_w
        if self.turning == 0.0 and view.ahead < p.avoid:
            self.turns += 1
            self.turning = 1.0 if view.open_left > view.open_right else -1.0
            if view.open_left == view.open_right:
                self.turning = self.rng.choice((-1.0, 1.0))
            self.until = p.clear + self.rng.uniform(0.0, p.extra)
        if self.turning:
            if view.ahead < max(self.until, p.avoid + 0.1):
                self.until -= p.settle
                return 0.0, self.turning * p.turn_w
            self.turning = 0.0
        if self.sips % p.meander_sips == 1:
            self.drift = self.rng.uniform(-p.meander, p.meander)
        w = self.drift
        if view.left < p.side or view.right < p.side:  # steer away from the closer side
            w = p.side_gain * (1 / max(view.right, 0.05) - 1 / max(view.left, 0.05))
        speed = (view.ahead - p.avoid) / (p.slow - p.avoid)
        v = p.max_v * min(1.0, max(0.25, speed))
        return v, max(-p.turn_w, min(p.turn_w, w))


def wander(robot: Pioneer, sips: int, params: WanderParams | None = None) -> WanderResult:
    """Wander for ``sips`` SIP cycles (100 ms each on a real robot), with the laser's
    returns when the robot has a laser running (a simulator's: ``robot.sim.start_laser()``)."""
    p = params or WanderParams()
    brain = Wanderer(p)
    distance = 0.0
    robot.enable_motors()
    last = robot.pose
    path = [(last[0], last[1])]
    for _ in range(sips):
        state = robot.wait_for_sip()
        distance += math.hypot(state.x - last[0], state.y - last[1])
        last = state.pose
        path.append((state.x, state.y))
        if state.bumped or state.stalled:
            brain.hit(rear=bool(state.bumpers_rear) and not state.bumpers_front)
        sim = getattr(robot, "sim", None)  # a real robot (or one over Zenoh) has no sim laser
        scan = sim.laser if sim is not None else None
        points = obstacles(state.sonar, robot.params, scan.points() if scan else None)
        robot.set_velocity(*brain.step(look(points, robot.params, p.margin)))
    robot.stop()
    return WanderResult(distance, brain.hits, brain.turns, path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("url", help="robot URL or port, or sim:// (docs/urls.md)")
    parser.add_argument("--seconds", type=float, default=30.0)
    args = parser.parse_args()
    with Pioneer.connect(args.url) as robot:
        if robot.sim is not None:
            robot.sim.start_laser()
        result = wander(robot, int(args.seconds * 10))
        print(f"travelled {result.distance:.2f} m, {result.turns} turns, {result.bumps} bumps")


if __name__ == "__main__":
    main()
