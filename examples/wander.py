"""Wander with artificial potential fields, as in the MATLAB Pioneer interface's example.

Each sonar reading closer than ``influence`` pushes the robot away from that sonar; a constant
pull draws it forward. The sum, in the robot's frame, gives the heading error and the speed.
A bumper hit stops the robot, backs it off and turns it away.

    python examples/wander.py tcp://127.0.0.1:8101 --seconds 60
    python examples/wander.py sim://                    # the built-in simulator, in-process
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

from robocli import Pioneer
from robocli.robots.pioneer import RobotParams


@dataclass
class WanderParams:
    influence: float = 1.2  #: m, sonar readings beyond this exert no force
    repulsion: float = 0.25  #: gain of the obstacle push
    attraction: float = 1.0  #: constant forward pull
    max_v: float = 0.4  #: m/s
    max_w: float = 1.2  #: rad/s
    turn_gain: float = 1.5  #: rad/s per rad of heading error


def potential_field(
    ranges: tuple[float, ...], robot: RobotParams, p: WanderParams
) -> tuple[float, float]:
    """(v, w) from one set of sonar ranges (metres, nan = no reading)."""
    fx, fy = p.attraction, 0.0
    for rng, pose in zip(ranges, robot.sonar, strict=False):
        if math.isnan(rng) or rng >= p.influence:
            continue
        d = max(rng, 0.05)
        push = p.repulsion * (1.0 / d - 1.0 / p.influence) / (d * d)
        fx -= push * math.cos(pose.th)
        fy -= push * math.sin(pose.th)
    heading = math.atan2(fy, fx)
    w = max(-p.max_w, min(p.max_w, p.turn_gain * heading))
    v = p.max_v * max(0.0, math.cos(heading)) * min(1.0, math.hypot(fx, fy) / p.attraction)
    return v, w


@dataclass
class WanderResult:
    distance: float  #: m travelled (odometry path length)
    bumps: int  #: bumper or stall events


def wander(robot: Pioneer, sips: int, params: WanderParams | None = None) -> WanderResult:
    """Wander for ``sips`` SIP cycles (100 ms each on a real robot)."""
    p = params or WanderParams()
    hits = 0
    distance = 0.0
    robot.enable_motors()
    backing_off = 0
    last = robot.pose
    for _ in range(sips):
        state = robot.wait_for_sip()
        distance += math.hypot(state.x - last[0], state.y - last[1])
        last = state.pose
        if state.bumped or state.stalled:
            if backing_off == 0:
                hits += 1
            backing_off = 10
        if backing_off:
            backing_off -= 1
            robot.set_velocity(-0.1 if backing_off > 5 else 0.0, p.max_w)
            continue
        robot.set_velocity(*potential_field(robot.sonar, robot.params, p))
    robot.stop()
    return WanderResult(distance, hits)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument("url", help="robot URL or port, or sim:// (docs/urls.md)")
    parser.add_argument("--seconds", type=float, default=30.0)
    args = parser.parse_args()
    with Pioneer.connect(args.url) as robot:
        result = wander(robot, int(args.seconds * 10))
        print(f"travelled {result.distance:.2f} m, {result.bumps} bumps")


if __name__ == "__main__":
    main()
