"""Fixtures: a built-in simulator on an ephemeral loopback port (a robot named by
ROBOCLI_PIONEER is tested by ``test_hardware.py``)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from robocli.sim.pioneer.server import PioneerSim
from robocli.sim.world import World
from tests.simulators import pioneer_on_loopback


@pytest.fixture
def sim() -> Iterator[PioneerSim]:
    """A P3-DX in the default room, 5x faster than real time."""
    with pioneer_on_loopback(time_scale=5.0) as simulator:
        yield simulator


@pytest.fixture
def empty_sim() -> Iterator[PioneerSim]:
    """A P3-DX in an empty world (sonar reads max range), 20x faster than real time."""
    with pioneer_on_loopback(time_scale=20.0, world=World.empty()) as simulator:
        yield simulator
