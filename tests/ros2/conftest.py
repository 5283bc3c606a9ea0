"""The bags the ROS 2 tests read: a Pioneer with its laser, an arm during an upload (the
CLI's upload --record --ros2) and the full hub, each recorded once per module, on first use."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.io.recordings import record_pioneer_drive

pytest.importorskip("rosbags")

from robocli.devices.hub.client import Hub
from robocli.hub_server import HubServer
from robocli.io.record import Recorder
from robocli.sim.abb.server import AbbSim
from robocli.sim.pioneer.server import PioneerSim
from tests.commands.helpers import run
from tests.devices.arm.conftest import port_of
from tests.waiting import wait_for

HUB_SENSORS = {"imu": {"rate": 100}, "adc": {"rate": 200, "channels": 0xFF},
               "camera": {"rate": 5, "resolution": "160x120"}, "laser": {"rate": 10},
               "gps": {"rate": 5}, "battery": {"rate": 5}, "sysinfo": {"rate": 5},
               "depth": {"rate": 5, "resolution": "160x120"},
               "stereo": {"rate": 5, "resolution": "160x120"}}  # fmt: skip


def pioneer_recording(path: Path, ros2: bool = True) -> None:
    """A Pioneer driving a curve with its laser on, recorded from the handshake on (a ROS 2
    bag, or robocli's JSON without ``ros2``)."""
    with PioneerSim("p3dx", time_scale=5.0) as sim:
        stats = record_pioneer_drive(path, sim.serve_tcp("127.0.0.1", 0), scans=2, ros2=ros2)
        assert stats.dropped == 0 and stats.decode_errors == 0


def _arm_bag(path: Path) -> None:
    with AbbSim("irb120", state_ms=5.0, feedback=True) as sim:
        motion, state = (port_of(u) for u in sim.serve_tcp("127.0.0.1", 0, 0))
        proc = run("upload", "arm", "127.0.0.1", "--motion-port", str(motion), "--state-port",
                   str(state), "--shape", "circle", "--points", "20", "--record", str(path),
                   "--ros2", timeout=120)  # fmt: skip
    assert proc.returncode == 0, proc.stderr


def _hub_bag(path: Path) -> None:
    with HubServer(port=0, sim=True) as srv, Recorder(path, ros2=True) as rec, \
            Hub.connect(f"127.0.0.1:{srv.port}") as hub:  # fmt: skip
        rec.add(hub)
        for name, options in HUB_SENSORS.items():
            hub.subscribe(name, **options)
        got: Counter[str] = Counter()

        def pulled() -> bool:
            for name in HUB_SENSORS:
                got[name] += len(hub.read(name))
            return all(got[n] >= 2 for n in HUB_SENSORS)

        wait_for(pulled, what="two samples of every hub sensor")
    assert rec.stats.dropped == 0 and rec.stats.decode_errors == 0


@pytest.fixture(scope="module")
def bags(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Path]]:
    """The three bags, each recorded once (lazily, on first use)."""
    root = tmp_path_factory.mktemp("bags")
    makers = {"pioneer": pioneer_recording, "arm": _arm_bag, "hub": _hub_bag}
    made: dict[str, Path] = {}

    class Lazy(dict[str, Path]):
        def __missing__(self, key: str) -> Path:
            path = root / f"{key}.mcap"
            makers[key](path)
            made[key] = path
            self[key] = path
            return path

    yield Lazy()
