"""Fixtures of the recording tests: the built-in simulators on ephemeral loopback ports."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

pytest.importorskip("mcap")

from robocli.hub_server import HubServer
from robocli.sim.abb.server import AbbSim
from robocli.sim.pioneer.server import PioneerSim
from tests.io.recordings import record_arm_move


@pytest.fixture
def pioneer_url() -> Iterator[str]:
    with PioneerSim("p3dx", time_scale=5.0) as simulator:
        yield simulator.serve_tcp("127.0.0.1", 0)


@pytest.fixture
def abb() -> Iterator[tuple[int, int]]:
    """An ABB simulator reporting JOINT_FEEDBACK with its clock every 5 ms: (motion, state)."""
    with AbbSim("irb120", state_ms=5.0, feedback=True) as simulator:
        motion, state = simulator.serve_tcp("127.0.0.1", 0, 0)
        yield int(motion.rsplit(":", 1)[1]), int(state.rsplit(":", 1)[1])


@pytest.fixture
def hub_server() -> Iterator[HubServer]:
    with HubServer(port=0, sim=True) as srv:
        yield srv


@pytest.fixture
def arm_recording(abb: tuple[int, int], tmp_path: Path) -> Path:
    """An arm's move recorded into tmp_path/arm.mcap (the tests of export and replay)."""
    path = tmp_path / "arm.mcap"
    record_arm_move(path, *abb)
    return path
