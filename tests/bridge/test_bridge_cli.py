"""``connect pioneer zenoh/<robot>`` and ``teleop pioneer zenoh/<robot>`` through a bridge:
the state as JSON, driving from a terminal, the refusal of a second driver (exit 4), and the
usage errors."""

from __future__ import annotations

import json
import os
import time
from collections.abc import Iterator

import pytest

from robocli.bridge import RemotePioneer
from robocli.sim.pioneer.server import PioneerSim
from tests.bridge.bridge_helpers import DEADLINE, bridge_process
from tests.commands.helpers import one_line_error, read_lines, run, running
from tests.commands.test_screens import terminal
from tests.waiting import wait_for


@pytest.fixture
def bridged(endpoint: str) -> Iterator[PioneerSim]:
    """A simulated Pioneer behind a bridge ``r1`` listening on ``endpoint``."""
    with PioneerSim() as simulator:
        url = simulator.serve_tcp("127.0.0.1", 0)
        with bridge_process(["pioneer", url, "--zenoh", endpoint, "--name", "r1"]):
            yield simulator


def test_connect_once_json_through_a_bridge(bridged, endpoint) -> None:
    proc = run("connect", "pioneer", "zenoh/r1", "--zenoh", endpoint, "--once", "--json")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["robot"] == "r1" and data["info"]["kind"] == "pioneer"
    state = data["state"]
    assert {"x", "y", "th", "v", "w", "battery", "sonar"} <= set(state)
    assert len(state["sonar"]) == 16 and state["battery"] > 10
    assert abs(state["t"] - data["state"]["t"]) < 1 and state["t"] > 1.7e9  # epoch seconds


def test_connect_streams_json_lines_and_ends_when_the_bridge_leaves(endpoint) -> None:
    with PioneerSim() as simulator:
        url = simulator.serve_tcp("127.0.0.1", 0)
        with bridge_process(["pioneer", url, "--zenoh", endpoint, "--name", "r1"]) as (b, _):
            with running("connect", "pioneer", "zenoh/r1", "--zenoh", endpoint, "--json") as c:
                assert c.stdout is not None and c.stderr is not None
                lines = read_lines(c.stdout, 2)
                counts = [json.loads(line)["state"]["sip_count"] for line in lines]
                assert len(counts) == 2 and counts[1] > counts[0]
                b.terminate()
                assert c.wait(DEADLINE) == 1
                assert "the bridge r1 left" in c.stderr.read()


def test_list_shows_the_robot_while_its_bridge_runs(bridged, endpoint) -> None:
    proc = run("list", "--zenoh", endpoint, "--json")
    assert proc.returncode == 0, proc.stderr
    assert {"name": "r1", "kind": "pioneer"} in json.loads(proc.stdout)


def test_connect_names_a_missing_bridge(bridged, endpoint) -> None:
    proc = run("connect", "pioneer", "zenoh/nobody", "--zenoh", endpoint, "--timeout", "1")
    assert "no bridge named 'nobody'" in one_line_error(proc, 3)


def test_the_endpoint_may_ride_in_the_url_as_in_the_library(bridged, endpoint) -> None:
    proc = run("connect", "pioneer", f"zenoh/r1?zenoh={endpoint}", "--once", "--json")
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["robot"] == "r1"
    proc = run("connect", "pioneer", f"zenoh/r1?zenoh={endpoint}", "--zenoh", "tcp/127.0.0.1:1")
    assert "give the Zenoh endpoint once" in one_line_error(proc, 2)


def test_zenoh_needs_a_zenoh_port() -> None:
    proc = run("connect", "pioneer", "sim", "--zenoh", "tcp/127.0.0.1:1")
    assert "zenoh/ROBOT" in one_line_error(proc, 2)


def test_a_bad_robot_name_is_a_usage_error() -> None:
    proc = run("bridge", "pioneer", "sim", "--zenoh", "tcp/127.0.0.1:1", "--name", "a/b")
    assert "--name" in one_line_error(proc, 2)


def test_teleop_drives_through_the_bridge_and_a_second_driver_is_refused(bridged, endpoint) -> None:
    with terminal("teleop", "pioneer", "zenoh/r1", "--zenoh", endpoint) as term:
        term.read_until(b"q or Ctrl-C quits")
        with RemotePioneer.connect("r1", endpoint) as watcher:
            driver = watcher.info  # who holds it: asked through the bridge
            assert driver["holder"] is not None
            deadline = time.monotonic() + DEADLINE
            while bridged.snapshot().trans_vel_set <= 0.1:  # a held key: presses keep coming
                assert time.monotonic() < deadline, "the robot does not move"
                os.write(term.master, b"w")
                term.read(0.05)
            second = run("teleop", "pioneer", "zenoh/r1", "--zenoh", endpoint)
            # (not a terminal: refused before asking; with one, the bridge refuses: below)
            assert one_line_error(second, 2)
            with pytest.raises(Exception, match="held by " + driver["holder"]):
                watcher.set_velocity(0.1)
        os.write(term.master, b"q")
        code, err = term.finish()
    assert code == 0 and err == "", err
    wait_for(lambda: bridged.snapshot().trans_vel_set == 0, "the robot stops after q")
