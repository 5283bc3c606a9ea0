"""robocli.views, robocli.running and robocli.io.jsonlines as a notebook user calls them,
against the built-in simulators over real loopback sockets."""

from __future__ import annotations

import json
import math
import os
import signal
import socket
import time

import pytest

from robocli import Arm, Laser, Pioneer
from robocli.errors import InvalidArgument, RobocliError, TransportError
from robocli.io.jsonlines import rounded, unix_stamped
from robocli.running import listening, shielded, sigterm_as_interrupt
from robocli.sim.hokuyo import HokuyoSim
from robocli.views import arm as arm_view
from robocli.views import laser as laser_view
from robocli.views import pioneer as pioneer_view
from tests.waiting import wait_for


def test_pioneer_snapshot_is_json_in_unix_time_with_the_simulators_laser() -> None:
    with Pioneer.connect("sim://") as robot:
        robot.wait_for_sip()
        pioneer_view.start_laser(robot, wait=True)
        wait_for(lambda: robot.sim is not None and robot.sim.laser is not None, "a laser scan")
        data = json.loads(json.dumps(rounded(pioneer_view.snapshot(robot, hokuyo={"a": 1}))))
        state = robot.state
        line = pioneer_view.state_line(state)
    assert abs(data["state"]["t"] - time.time()) < 60  # Unix time, not monotonic
    assert data["state"]["t_mono"] == pytest.approx(state.t, abs=1e3)
    assert data["hokuyo"] == {"a": 1} and list(data)[-1] == "laser"
    assert len(data["laser"]["ranges"]) == len(data["laser"]["angles"]) > 0
    assert "battery" in line and "m/s" in line
    assert pioneer_view.pose_text(1, -0.5, math.pi / 2) == "x +1.000 m  y -0.500 m  th +90.0 deg"
    assert pioneer_view.sonar_text([1.0, float("nan")]) == [" 1.00   -  "]


def test_arm_states_describe_each_state_and_fit_a_line() -> None:
    with Arm.connect("sim://") as arm:
        stream = arm_view.states(arm, timeout=5.0)
        first, second = next(stream), next(stream)
    assert second["t"] >= first["t"] and abs(first["t"] - time.time()) < 60
    assert len(first["joints_rad"]) == 6 and len(first["tcp_m"]) == 3
    assert first["joints_deg"][0] == pytest.approx(math.degrees(first["joints_rad"][0]))
    assert len(arm_view.state_text(first)) < 100


def test_laser_views_give_identity_lines_a_scan_line_and_si_json() -> None:
    with Laser.connect("sim://utm-30lx") as laser:
        scan = laser.scan()
        data = laser_view.scan_json(laser, scan)
        lines = laser_view.identity_lines(laser)
    assert data["model"].startswith("UTM") and abs(data["t"] - time.time()) < 60
    assert len(data["ranges"]) == len(data["angles"]) == len(scan.ranges)
    assert len(lines) == 3 and "serial" in lines[0] and "rpm" in lines[2]
    assert "valid" in laser_view.scan_line(scan)


def test_listening_names_what_is_wrong_with_a_bind_address() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with HokuyoSim("utm-30lx") as sim, pytest.raises(RobocliError) as busy:
            with listening("127.0.0.1"):
                sim.serve_tcp("127.0.0.1", port)
    with HokuyoSim("utm-30lx") as sim, pytest.raises(InvalidArgument):
        with listening("192.0.2.1"):  # not this machine's
            sim.serve_tcp("192.0.2.1", 0)
    assert not isinstance(busy.value, TransportError)  # taken: a failure, not "unreachable"


def test_sigterm_interrupts_the_block_and_shielded_steps_ignore_it() -> None:
    before = signal.getsignal(signal.SIGTERM)
    with pytest.raises(KeyboardInterrupt), sigterm_as_interrupt():
        os.kill(os.getpid(), signal.SIGTERM)
        wait_for(lambda: False, "SIGTERM as KeyboardInterrupt", timeout=10)
    with sigterm_as_interrupt(), shielded():
        os.kill(os.getpid(), signal.SIGTERM)  # ignored: the step goes on
    assert signal.getsignal(signal.SIGTERM) == before


def test_rounded_and_unix_stamped() -> None:
    now = time.monotonic()
    out = rounded(unix_stamped({"t": now, "x": 0.123456789, "v": float("nan")}))
    assert out["t_mono"] == round(now, 6) and out["x"] == 0.1235 and out["v"] is None
    assert abs(out["t"] - time.time()) < 1
