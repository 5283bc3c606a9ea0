"""``robocli doctor``: its JSON against running built-in simulators (addresses from the
environment) and with nothing running; no probe hangs or disturbs a device (issue 13: 20)."""

from __future__ import annotations

import importlib.util
import json
import os
import socket
import time
from collections.abc import Iterator
from typing import Any

import pytest

from robocli import __version__
from robocli.defaults import ARM_ENV, HUB_ENV, PIONEER_ENV
from robocli.devices.pioneer import Pioneer
from robocli.errors import RobocliError
from robocli.hub_server import HubServer
from robocli.sim.abb.server import AbbSim
from robocli.sim.pioneer.server import PioneerSim
from tests.commands.helpers import run
from tests.waiting import wait_for

PROBES = ("pioneer", "arm_motion", "arm_state", "hub")


def doctor(*args: str, **env: str) -> dict[str, Any]:
    proc = run("doctor", "--json", *args, env={**os.environ, **env}, timeout=60)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    return json.loads(proc.stdout)  # type: ignore[no-any-return]


def dead_port() -> int:
    """A loopback port nothing listens on (bound, then closed)."""
    with socket.create_server(("127.0.0.1", 0)) as s:
        return int(s.getsockname()[1])


@pytest.fixture
def sims() -> Iterator[tuple[str, AbbSim, HubServer, int, int]]:
    with PioneerSim() as pioneer, AbbSim(state_ms=20.0) as arm, \
            HubServer(bind="127.0.0.1", port=0, sim=True) as hub:  # fmt: skip
        motion, state = (int(u.rsplit(":", 1)[1]) for u in arm.serve_tcp("127.0.0.1", 0, 0))
        yield pioneer.serve_tcp("127.0.0.1", 0), arm, hub, motion, state


def test_the_report_against_running_simulators(sims: tuple[Any, ...]) -> None:
    url, _arm, hub, motion, state = sims
    report = doctor("--motion-port", str(motion), "--state-port", str(state),
                    **{PIONEER_ENV: url, ARM_ENV: "127.0.0.1",
                       HUB_ENV: f"127.0.0.1:{hub.port}"})  # fmt: skip
    assert set(report) == {"t", "versions", "c_core", "extras", "serial", "addresses", "problems"}
    assert abs(report["t"] - time.time()) < 600  # Unix epoch seconds, as every --json
    assert report["versions"]["robocli"] == __version__
    assert report["versions"]["packages"]["pyserial"]  # installed: a version string
    assert report["c_core"]["loaded"] is True and report["c_core"]["error"] is None
    assert report["extras"]["plot"]["installed"] == (importlib.util.find_spec("matplotlib")
                                                     is not None)  # fmt: skip
    assert report["extras"]["test"]["installed"] is True  # this suite runs
    for port in report["serial"]["ports"]:
        assert isinstance(port["may_open"], bool) and port["device"]
    addresses = report["addresses"]
    assert list(addresses) == list(PROBES)
    for name in PROBES:
        assert addresses[name]["answers"] is True, addresses[name]
        assert addresses[name]["source"] == "env" and addresses[name]["ms"] >= 0
    assert addresses["pioneer"]["address"] == url and "ARCOS" in addresses["pioneer"]["detail"]
    assert addresses["arm_state"]["address"] == f"127.0.0.1:{state}"
    assert addresses["hub"]["env"] == HUB_ENV
    # the probes left the devices as they were: the robot takes a client, the hub forgot us
    wait_for(lambda: not any(c.connected for c in hub.clients), "the hub's probe client left")

    def robot_free() -> bool:
        try:
            with Pioneer.connect(url, timeout=2.0):
                return True
        except RobocliError:
            return False

    wait_for(robot_free, "the simulated robot accepts a client after the probe")


def test_the_text_report_names_each_part(sims: tuple[Any, ...]) -> None:
    url, _arm, hub, motion, state = sims
    proc = run("doctor", "--pioneer", url, "--arm", "127.0.0.1", "--motion-port", str(motion),
               "--state-port", str(state), "--hub", f"127.0.0.1:{hub.port}",
               timeout=60)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    lines = {line.split()[0]: line for line in proc.stdout.splitlines()}
    assert lines["robocli"].startswith(f"robocli {__version__},")
    assert "loaded" in lines["C"] and f"{url} (given): answers" in lines["pioneer"]
    assert {"packages", "extras", "arm_motion", "arm_state", "hub"} <= set(lines)


def test_the_report_with_nothing_running() -> None:
    ports = [dead_port() for _ in range(3)]
    report = doctor("--motion-port", str(ports[1]), "--state-port", str(ports[2]),
                    **{PIONEER_ENV: f"tcp://127.0.0.1:{ports[0]}", ARM_ENV: "127.0.0.1",
                       HUB_ENV: f"127.0.0.1:{ports[0]}"})  # fmt: skip
    for name in PROBES:
        entry = report["addresses"][name]
        assert entry["answers"] is False and "refused" in entry["detail"], entry
    assert report["c_core"]["loaded"] is True


def test_unreachable_and_unresolvable_addresses_end_with_a_reason() -> None:
    """A TEST-NET address (packets go nowhere) and a name no resolver knows: each probe
    ends within its bound with a reason; a malformed address is reported, not raised."""
    report = doctor("--timeout", "0.3", "--arm", "bad host",
                    **{PIONEER_ENV: "tcp://robocli-doctor.invalid:8101",
                       HUB_ENV: "192.0.2.1:1500"})  # fmt: skip
    addresses = report["addresses"]
    for name in PROBES:
        assert addresses[name]["answers"] is False and addresses[name]["detail"], addresses[name]
    assert "not a host name" in addresses["arm_motion"]["detail"]
    assert addresses["pioneer"]["source"] == "env" and addresses["arm_state"]["source"] == "given"


def test_a_serial_port_is_checked_not_opened(tmp_path: Any) -> None:
    report = doctor(**{PIONEER_ENV: str(tmp_path / "ttyUSB9")})
    entry = report["addresses"]["pioneer"]
    assert entry["answers"] is None and "no such serial port" in entry["detail"]
    assert doctor(**{PIONEER_ENV: "sim"})["addresses"]["pioneer"]["answers"] is None


def test_a_silent_server_is_no_answer_not_a_hang() -> None:
    """Something that accepts connections and never speaks, on every address: each probe
    gives up after its own timeout (the motion port only has to accept)."""
    with socket.create_server(("127.0.0.1", 0), backlog=16) as silent:
        port = str(silent.getsockname()[1])
        report = doctor("--timeout", "0.3", "--motion-port", port, "--state-port", port,
                        **{PIONEER_ENV: f"127.0.0.1:{port}", ARM_ENV: "127.0.0.1",
                           HUB_ENV: f"127.0.0.1:{port}"})  # fmt: skip
    addresses = report["addresses"]
    assert "no ARCOS reply" in addresses["pioneer"]["detail"]
    assert "no state message" in addresses["arm_state"]["detail"]
    assert addresses["arm_motion"]["answers"] is True
    assert addresses["hub"]["answers"] is False and addresses["hub"]["detail"]
