"""Default addresses from the environment: every command that takes a robot, arm or hub
address reads its variable, shows it in --help, and an explicit --file still wins
(issue 13: 18). The suite reads the same names (tests/hardware.py) and clears them, so
these tests set them per process."""

from __future__ import annotations

import json
import os
from collections.abc import Iterator

import pytest

from robocli.defaults import ARM_ENV, HUB_ENV, PIONEER_ENV
from robocli.hub_server import HubServer
from robocli.sim.abb.server import AbbSim
from robocli.sim.pioneer.server import PioneerSim
from tests.commands.helpers import one_line_error, run
from tests.paths import DATA, EXAMPLES

ARM_DATA = DATA / "simple_message"


def env(**values: str) -> dict[str, str]:
    return {**os.environ, **values}


@pytest.fixture(scope="module")
def pioneer_url() -> Iterator[str]:
    with PioneerSim() as simulator:
        yield simulator.serve_tcp("127.0.0.1", 0)


@pytest.fixture(scope="module")
def hub_address() -> Iterator[str]:
    with HubServer(bind="127.0.0.1", port=0, sim=True) as srv:
        yield f"127.0.0.1:{srv.port}"


def test_the_suite_and_the_cli_read_the_same_names() -> None:
    from tests.hardware import VARIABLES

    assert VARIABLES == {"pioneer": PIONEER_ENV, "arm": ARM_ENV, "hub": HUB_ENV}
    assert (PIONEER_ENV, ARM_ENV, HUB_ENV) == ("ROBOCLI_PIONEER", "ROBOCLI_ARM", "ROBOCLI_HUB")
    assert not {PIONEER_ENV, ARM_ENV, HUB_ENV} & set(os.environ)  # read, then cleared


@pytest.mark.parametrize(
    ("words", "variable"),
    [
        (("connect", "pioneer"), PIONEER_ENV),
        (("teleop", "pioneer"), PIONEER_ENV),
        (("dump", "pioneer"), PIONEER_ENV),
        (("connect", "arm"), ARM_ENV),
        (("upload", "arm"), ARM_ENV),
        (("monitor", "arm"), ARM_ENV),
        (("dump", "arm"), ARM_ENV),
        (("teleop", "arm"), ARM_ENV),
        (("subscribe",), HUB_ENV),
        (("connect", "hub"), HUB_ENV),
        (("dump", "hub"), HUB_ENV),
        (("serial",), HUB_ENV),
    ],
)
def test_help_names_the_variable(words: tuple[str, ...], variable: str) -> None:
    proc = run(*words, "--help", env={**os.environ, "COLUMNS": "100"})
    assert proc.returncode == 0, proc.stderr
    assert f"env var: {variable}" in " ".join(proc.stdout.split()), proc.stdout


def test_connect_pioneer_takes_its_port_from_the_environment(pioneer_url: str) -> None:
    proc = run("connect", "pioneer", "--once", "--json", "--no-laser",
               env=env(**{PIONEER_ENV: pioneer_url}))  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["identity"]["type"] == "Pioneer"


def test_dump_file_wins_over_the_environment() -> None:
    capture = str(EXAMPLES / "pioneer_drive.jsonl")
    proc = run("dump", "pioneer", "--file", capture, "-n", "2",
               env=env(**{PIONEER_ENV: "tcp://127.0.0.1:1"}))  # fmt: skip
    assert proc.returncode == 0 and len(proc.stdout.splitlines()) == 2, proc.stderr
    proc = run("dump", "arm", "--file", str(ARM_DATA / "exchange_le.jsonl"), "-n", "2",
               env=env(**{ARM_ENV: "127.0.0.1"}))  # fmt: skip
    assert proc.returncode == 0 and len(proc.stdout.splitlines()) == 2, proc.stderr


def test_connect_arm_takes_its_host_from_the_environment() -> None:
    with AbbSim(state_ms=10.0) as sim:
        _, state = sim.serve_tcp("127.0.0.1", 0, 0)
        proc = run("connect", "arm", "--state-port", state.rsplit(":", 1)[1], "--once",
                   "--json", env=env(**{ARM_ENV: "127.0.0.1"}))  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert len(json.loads(proc.stdout)["joints_rad"]) == 6


def test_hub_commands_take_the_hub_from_the_environment(hub_address: str) -> None:
    proc = run("connect", "hub", "--once", "--json", env=env(**{HUB_ENV: hub_address}))
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["hub"] == f"tcp://{hub_address}"
    # `serial PORT` alone: the hub of $ROBOCLI_HUB answers (this one serves no serial port)
    proc = run("serial", "/dev/ttyUSB0", "--recv", "1", env=env(**{HUB_ENV: hub_address}))
    line = one_line_error(proc, 4)
    assert "serves no serial port" in line, line
    line = one_line_error(run("serial", "/dev/ttyUSB0"), 2)
    assert f"PORT alone with ${HUB_ENV} set" in line, line
