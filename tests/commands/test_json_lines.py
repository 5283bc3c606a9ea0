"""``--json`` is one thing everywhere (issue 22): JSON Lines, ``--once`` included; every
``t`` Unix time; SI quantities; a frame's ``dir`` as capture files say it (``c2s``/``s2c``).
And the old spellings of renamed options still work, saying their new one."""

from __future__ import annotations

import json
import math
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from robocli.hub_server import HubServer
from tests.commands.helpers import run


def _lines(*args: str) -> list[dict[str, object]]:
    done = run(*args, timeout=120)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    return [json.loads(line) for line in lines]  # each line is a whole document


@pytest.mark.parametrize(
    "args",
    [("connect", "pioneer", "sim", "--once", "--json"),
     ("connect", "arm", "sim", "--once", "--json"),
     ("connect", "laser", "sim", "--once", "--json"),
     ("doctor", "--json", "--timeout", "0.2")],
)  # fmt: skip
def test_once_json_is_one_line(args: tuple[str, ...]) -> None:
    assert len(_lines(*args)) == 1


def test_dump_laser_json_has_unix_time_and_capture_directions() -> None:
    rows = _lines("dump", "laser", "sim", "-n", "2", "--json")
    now = time.time()
    assert all(isinstance(r["t"], float) and abs(r["t"] - now) < 300 for r in rows), rows[:2]
    assert rows[0]["t_rel"] == 0.0
    assert {r["dir"] for r in rows} == {"c2s", "s2c"}


@pytest.fixture(scope="module")
def hub() -> Iterator[str]:
    with HubServer(bind="127.0.0.1", port=0, sim=True) as srv:
        yield f"127.0.0.1:{srv.port}"


def test_subscribe_imu_json_is_si(hub: str) -> None:
    """The hub sends g, deg/s and uT; JSON gives m/s^2, rad/s and T, as recordings do: the
    simulated IMU at rest measures about 1 g, so |a| is about 9.8 m/s^2."""
    rows = _lines("subscribe", "imu", "--hub", hub, "-r", "50", "--json", "-n", "5")
    for row in rows:
        a = math.sqrt(sum(float(row[k]) ** 2 for k in ("ax", "ay", "az")))  # type: ignore[arg-type]
        assert 5.0 < a < 15.0, row
        m = max(abs(float(row[k])) for k in ("mx", "my", "mz"))  # type: ignore[arg-type]
        assert m < 1e-2, row  # tesla: the Earth's field is about 5e-5 T


def test_connect_hub_uses_robocli_sensor_names(hub: str) -> None:
    (info,) = _lines("connect", "hub", hub, "--once", "--json", "--window", "0.1")
    sensors = set(info["sensors"])  # type: ignore[arg-type]
    assert {"sysinfo", "laser", "depth", "stereo"} <= sensors
    assert not {"computer", "hokuyo", "kinect", "camera_stereo"} & sensors


def test_an_old_spelling_works_and_says_the_new_one(tmp_path: Path) -> None:
    out = tmp_path / "c.json"
    done = run("traj", "circle", "--out", str(out), "--points", "10")
    assert done.returncode == 0, done.stderr
    assert out.exists()
    notes = done.stderr.splitlines()
    assert notes == [
        "robocli: --out is now --output (the old spelling goes in the next release)",
        "robocli: --points is now --count (the old spelling goes in the next release)",
    ]


def test_connect_arm_text_fits_a_terminal_line() -> None:
    """The live view printed about 300 characters a state, 10 a second (issue 22): one
    state is now one line of a terminal's width; --json keeps every field."""
    done = run("connect", "arm", "sim", "--count", "3")
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert len(lines) == 3 and all(len(line) < 100 and "tcp" in line for line in lines), lines
