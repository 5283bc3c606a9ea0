"""Soak (`make soak`, not in `make test`): 10 minutes of real time against the simulator's
2 s watchdog; the keep-alive must never let it trip, while driving or idle."""

from __future__ import annotations

import time

import numpy as np
import pytest

from robocli.devices.pioneer import Pioneer
from robocli.sim.pioneer.server import PioneerSim
from robocli.sim.world import World


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_ten_minutes_without_a_watchdog_trip() -> None:
    with PioneerSim("p3dx", world=World.empty()) as sim:
        url = sim.serve_tcp("127.0.0.1", 0)
        with Pioneer.connect(url) as robot:
            robot.enable_motors()
            end = time.monotonic() + 600
            phase = 0
            while time.monotonic() < end:
                # alternate: a slow circle (set-points refreshed) and standing still (PULSE)
                if phase % 2 == 0:
                    robot.set_velocity(0.1, 0.2)
                else:
                    robot.stop()
                phase += 1
                time.sleep(30)
                assert sim.snapshot().watchdog_trips == 0
            # the watchdog sees the gaps between any two packets from the client
            gaps = np.diff(np.array(robot.stats.tx_times))
            sips = np.diff(np.array(robot.stats.sip_times))
        assert sim.snapshot().watchdog_trips == 0
    assert gaps.max() <= 0.5, gaps.max()
    assert abs(sips.mean() - 0.1) < 0.001 and sips.std() < 0.002
