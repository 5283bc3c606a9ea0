"""One surface: the device URL grammar (addresses.parse_device_url), what a sim:// URL
starts, and the old spellings kept for a release with a one-time DeprecationWarning."""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from typing import Any

import pytest

import robocli
from robocli.addresses import ARM_PORTS, InvalidURL, parse_device_url
from robocli.devices import base
from robocli.errors import InvalidArgument
from robocli.sim.abb.server import AbbSim


@pytest.mark.parametrize(("url", "kind", "field", "value"), [
    ("sim", "sim", "model", ""),
    ("sim://", "sim", "model", ""),
    ("sim://p3dx?time_scale=4", "sim", "options", {"time_scale": "4"}),
    ("tcp://127.0.0.1:8101", "tcp", "port", 8101),
    ("[::1]:8101", "tcp", "host", "::1"),
    ("/dev/ttyUSB0", "serial", "target", "/dev/ttyUSB0"),
    ("socket://127.0.0.1:4001", "serial", "target", "socket://127.0.0.1:4001"),
    ("zenoh/lab-robot", "zenoh", "name", "lab-robot"),
    ("zenoh/lab-robot?zenoh=tcp/10.0.0.1:7447", "zenoh", "options",
     {"zenoh": "tcp/10.0.0.1:7447"}),
])  # fmt: skip
def test_one_grammar_for_every_device(url: str, kind: str, field: str, value: Any) -> None:
    parsed = parse_device_url(url)
    assert parsed.kind == kind
    assert getattr(parsed, field) == value


def test_an_arms_two_ports_ride_in_its_url() -> None:
    parsed = parse_device_url("tcp://10.0.0.5?motion=21000&state=21002", ports=ARM_PORTS)
    assert (parsed.host, parsed.ports) == ("10.0.0.5", {"motion": 21000, "state": 21002})
    assert parse_device_url("10.0.0.5", ports=ARM_PORTS).ports == {}


@pytest.mark.parametrize(("url", "ports", "reason"), [
    ("tcp://h:1?motion=2", ARM_PORTS, "without a port"),
    ("tcp://h?motion=0", ARM_PORTS, "1..65535"),
    ("tcp://h?speed=3", ARM_PORTS, "unknown option"),
    ("tcp://h?motion=1&motion=2", ARM_PORTS, "repeated"),
    ("loop://", (), "echoes"),
    ("sim://no such", (), "model name"),
    ("zenoh/", (), "zenoh/NAME"),
    ("zenoh/r1?connect=tcp/h:1", (), "zenoh=ENDPOINT"),
    ("zenoh/r1?zenoh=", (), "zenoh=ENDPOINT"),
    ("zenoh/r1?zenoh=a&zenoh=b", (), "repeated"),
    ("", (), "empty"),
    ("x" * 5000, (), "longer than"),
])  # fmt: skip
def test_a_malformed_url_is_a_usage_error(url: str, ports: tuple[str, ...], reason: str) -> None:
    with pytest.raises(InvalidURL, match=reason):
        parse_device_url(url, ports=ports)


def test_an_arm_url_carries_its_ports() -> None:
    with AbbSim(state_ms=5.0) as sim:
        motion, state = (int(u.rsplit(":", 1)[1]) for u in sim.serve_tcp("127.0.0.1", 0, 0))
        with robocli.Arm.connect(f"tcp://127.0.0.1?motion={motion}&state={state}") as arm:
            assert arm.motion_address == ("127.0.0.1", motion)
            assert arm.wait_for_state(20.0) is not None
        with pytest.raises(InvalidArgument, match="give it once"):
            robocli.Arm.connect(f"tcp://127.0.0.1?motion={motion}", motion_port=motion + 1)


def test_a_sim_url_passes_its_options_to_the_simulator() -> None:
    with robocli.Pioneer.connect("sim://p3at?time_scale=4&seed=3") as robot:
        assert robot.params.subtype == "p3at"
        assert robot.simulator is not None
        assert robot.simulator.server.time_scale == 4.0
    with pytest.raises(InvalidArgument, match="refused"):
        robocli.Pioneer.connect("sim://?no_such_option=1")
    with pytest.raises(InvalidArgument, match="ephemeral loopback"):
        robocli.Laser.connect("sim://?port=10940")


def _warnings_of(call: Callable[[], object]) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        call()
    return [str(w.message) for w in caught if w.category is DeprecationWarning]


def test_an_old_spelling_works_and_warns_once_naming_the_new(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(base, "_warned", set())
    with robocli.Laser.connect("sim://") as laser:
        scans: list[Any] = []
        first = _warnings_of(lambda: laser.on_scan(scans.append))
        assert first == ['Laser.on_scan is deprecated; use Laser.add_listener(..., kind="scans")']
        assert _warnings_of(lambda: laser.on_scan(scans.append)) == []  # once
        laser.start()
        laser.read(timeout=20.0)
        assert scans  # the old name still does its job
    with robocli.Pioneer.connect("sim://") as robot:
        assert _warnings_of(lambda: robot.connected) == [
            "Pioneer.connected is deprecated; use Pioneer.alive"
        ]
        assert robot.connected is True
    with pytest.warns(DeprecationWarning, match=r"Hub\.connect\(host=\) is deprecated"):
        hub = robocli.Hub.connect(host="sim://")  # the old name of url
    with hub:
        assert hub.alive
    messages = _warnings_of(lambda: hub.close(quit=True))
    assert messages == ["Hub.close(quit=) is deprecated; use Hub.close(stop=)"]


def test_baudrate_is_the_one_spelling(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(base, "_warned", set())
    messages = _warnings_of(lambda: robocli.Pioneer.connect("sim://", baud=9600).close())
    assert messages == ["Pioneer.connect(baud=) is deprecated; use Pioneer.connect(baudrate=)"]
    with pytest.raises(InvalidArgument, match="give baudrate= only"):
        robocli.Pioneer.connect("sim://", baud=9600, baudrate=38400)


def test_simulator_only_methods_are_a_part_under_robot_sim() -> None:
    from robocli.devices.pioneer.simulated import PioneerSimulator

    with robocli.Pioneer.connect("sim://?time_scale=4") as robot:
        sim = robot.sim
        assert isinstance(sim, PioneerSimulator)
        scans: list[Any] = []
        robot.add_listener(scans.append, kind="laser")
        sim.start_laser()
        assert len(sim.wait_for_laser(20.0)) > 0 and sim.laser is not None
        sim.set_pose(1.0, -0.5, 0.0)
        deadline = time.monotonic() + 20.0
        status = sim.status(20.0)
        while status.true_pose[0] != pytest.approx(1.0):  # the teleport lands within a step
            assert time.monotonic() < deadline, "the teleport never showed"
            status = sim.status(20.0)
        assert scans
        # the robot's own surface no longer carries the simulator's names, and its parts
        # (the simulator's, the keep-alive) are held, not inherited
        from robocli.devices.pioneer.keepalive import KeepAlive

        public = {n for n in vars(type(robot)) if not n.startswith("_")}
        assert not {"start_laser", "sim_status", "set_simulator_pose"} & public
        assert not {KeepAlive, PioneerSimulator} & set(type(robot).__mro__)
        assert isinstance(robot._keeper, KeepAlive)
        robot.config = {**(robot.config or {}), "serial": "1234"}  # a real robot's CONFIG
        robot.identity = type(robot.identity)("Pioneer", "Pioneer", "p3dx")
        assert robot.sim is None
