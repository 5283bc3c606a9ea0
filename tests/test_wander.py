"""``make demo``'s wander explores the room: on the built-in simulator (ten times faster than
real time, its default room of 12 m x 10 m with boxes, the laser on as in the demo), for the
demo's run (:data:`demo.WANDER_SIPS`), the robot's true path visits many distinct 1 m cells,
leaves the corridor it starts in and keeps moving to the end of its run, turning away from
the walls. The demo's wander used to drive 7.1 m straight down that corridor to the first
wall and stop there: one line in its figure. The sonar alone is enough to explore too."""

from __future__ import annotations

import math
import sys
import threading
from typing import Any

import pytest

from robocli import Pioneer
from robocli.sim.pioneer.server import PioneerSim
from tests.paths import EXAMPLES

sys.path.insert(0, str(EXAMPLES))
from demo import WANDER_SIPS
from wander import wander


def run(sips: int, laser: bool) -> list[tuple[float, float]]:
    """The simulator's true (x, y) along a wander of ``sips`` SIPs, and its end time."""
    path: list[tuple[float, float]] = []
    done: list[Any] = []
    with PioneerSim("p3dx", time_scale=10.0) as sim:
        url = sim.serve_tcp("127.0.0.1", 0)
        with Pioneer.connect(url) as robot:
            if laser:
                robot.sim.start_laser()
                robot.sim.wait_for_laser(timeout=10)
            runner = threading.Thread(target=lambda: done.append(wander(robot, sips)))
            runner.start()
            while runner.is_alive():  # the truth, sampled along the run
                truth = sim.snapshot()
                path.append((truth.x, truth.y))
                runner.join(0.02)
            runner.join(60)
        assert done, "the wander did not finish"
        assert sim.snapshot().sim_time >= sips * 0.1 * 0.9  # it ran for its SIPs
    return path


def explored(path: list[tuple[float, float]], cells: int) -> None:
    visited = {(math.floor(x), math.floor(y)) for x, y in path}
    assert len(visited) >= cells, sorted(visited)  # a run down the corridor visits 8
    ys = [y for _, y in path]
    assert max(ys) - min(ys) > 2.5  # out of the corridor along y = 0, into the room
    last = path[-len(path) // 3 :]
    moved = sum(math.dist(a, b) for a, b in zip(last, last[1:], strict=False))
    assert moved > 2.0  # still going in the last third of its run


def test_the_demos_wander_explores_the_room() -> None:
    explored(run(WANDER_SIPS, laser=True), cells=20)


@pytest.mark.parametrize("sips", [600])
def test_the_sonar_alone_is_enough(sips: int) -> None:
    explored(run(sips, laser=False), cells=15)
