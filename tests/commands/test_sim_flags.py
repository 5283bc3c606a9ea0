"""`robocli sim pioneer --no-laser / --georef`: the simulator's laser and GPS from the command
line, checked with the client over the simulator's real socket."""

from __future__ import annotations

import math
import signal

import pytest

from robocli import Pioneer
from robocli.errors import TimeoutError
from tests.commands.helpers import one_line_error, run, running


def _served_url(proc) -> str:  # type: ignore[no-untyped-def]
    assert proc.stdout is not None
    line = proc.stdout.readline()  # "robot 1: p3dx on tcp://127.0.0.1:PORT"
    assert " on tcp://" in line, line
    return line.rsplit(" on ", 1)[1].strip()


def test_georef_gives_simstat_a_gps_fix_and_the_laser_is_on_by_default() -> None:
    with running("sim", "pioneer", "--port", "0", "--georef", "42.3601,-71.0589,10") as proc:
        with Pioneer.connect(_served_url(proc), laser=True) as robot:
            assert len(robot.sim.wait_for_laser(timeout=5.0)) == 181
            status = robot.sim.status()
            assert status.gps is not None
            assert status.gps.latitude == pytest.approx(42.3601, abs=1e-4)
            assert status.gps.longitude == pytest.approx(-71.0589, abs=1e-4)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(30) == 130  # interrupted, as every command


def test_no_laser_answers_35_as_adsel() -> None:
    with running("sim", "pioneer", "--port", "0", "--no-laser") as proc:
        with Pioneer.connect(_served_url(proc)) as robot:
            robot.sim.start_laser(-math.pi / 2, math.pi / 2, math.radians(1))
            with pytest.raises(TimeoutError):
                robot.sim.wait_for_laser(timeout=0.5)  # several SIP periods: no scan ever comes
            assert robot.sim.status().gps is None
        proc.send_signal(signal.SIGINT)
        assert proc.wait(30) == 130  # interrupted, as every command


@pytest.mark.parametrize("value", ["north", "42.36", "91,0", "0,181", "nan,0", "1,2,3,4"])
def test_a_bad_georef_is_a_usage_error(value: str) -> None:
    line = one_line_error(run("sim", "pioneer", "--port", "0", "--georef", value), 2)
    assert "--georef" in line and value in line, line
