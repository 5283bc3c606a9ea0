"""The ros4mat paper's proof, end to end on one machine: pycreate2 (a third-party toolkit,
unmodified) drives the iRobot Create simulator through the hub's virtual serial port:
toolkit -> local pty (``robocli serial HUB PORT --pty``) -> hub -> the hub's serial port (the
simulator's pty) -> the Create. Only the port string changes."""

from __future__ import annotations

import json
import math
import os
import re
import signal
import subprocess
import sys
import termios
from pathlib import Path

import pytest

from robocli.hub_server import HubServer
from robocli.sim.create import CreateSim
from tests.commands.helpers import read_lines, running
from tests.paths import DATA

pytest.importorskip("pycreate2")
pytestmark = pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs pseudo-terminals")

DRIVER = DATA / "create" / "pycreate2_drive.py"
SAFE, OFF = 2, 0
WAIT = 10.0


def _drive(port: str) -> dict[str, object]:
    run = subprocess.run([sys.executable, str(DRIVER), port], capture_output=True, text=True,
                         timeout=180)  # fmt: skip
    assert run.returncode == 0, run.stderr
    result: dict[str, object] = json.loads(
        [ln for ln in run.stdout.splitlines() if ln.startswith("{")][-1]
    )
    return result


def _speed(path: str) -> int:
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        return int(termios.tcgetattr(fd)[5])
    finally:
        os.close(fd)


def test_pycreate2_through_the_hubs_virtual_serial_port(tmp_path: Path) -> None:
    """Starts, safe mode, drives, reads group 100: its odometry agrees with the simulator's
    truth, and the 115200 baud pycreate2 set on the local pty reached the simulator's line."""
    token = tmp_path / "hub.token"
    token.write_text("create-lab\n")
    with CreateSim() as sim:  # 7.5 m free ahead of the start
        line = sim.serve_pty()
        x0, y0, th0 = (lambda s: (s.x, s.y, s.th))(sim.snapshot())
        with HubServer(port=0, sim=False, serial_ports=[line], token=b"create-lab") as hub, \
                running("serial", f"127.0.0.1:{hub.port}", line, "--pty", "--token-file",
                        str(token)) as relay:  # fmt: skip
            assert relay.stdout is not None
            (pty_path,) = read_lines(relay.stdout, 1)
            got = _drive(pty_path.strip())  # the only change: the port string
            end = sim.wait_until(lambda s: s.mode == OFF, WAIT)  # pycreate2's clean-up
            assert _speed(line) == termios.B115200
            relay.send_signal(signal.SIGINT)
            assert relay.wait(WAIT) == 130
    assert got["modes"] == [SAFE] and int(got["reads"]) > 10  # type: ignore[call-overload]
    distance, angle = float(got["distance"]), float(got["angle"])  # type: ignore[arg-type]
    assert distance >= 300 and angle >= 90
    assert abs(distance - end.distance_mm) <= 1.0 and abs(angle - end.angle_deg) <= 1.0
    moved = math.hypot(end.x - x0, end.y - y0) * 1000.0  # turning in place adds no path
    assert abs(moved - distance) <= 2.0
    assert abs(math.degrees(end.th - th0) - angle) <= 1.0
    assert end.dropped_bytes == 0 and end.commands["DRIVE_DIRECT"] >= 3


def test_the_whole_chain_as_processes() -> None:
    """What docs/serial.md shows: `robocli sim create --pty`, `robocli serve --serial PATH`,
    `robocli serial HUB PATH --pty`, then the toolkit on the printed pty: four processes."""
    with running("sim", "create", "--pty") as create:
        assert create.stdout is not None
        (said,) = read_lines(create.stdout, 1)
        found = re.search(r"on (/dev/\S+)", said)
        assert found, said
        line = found.group(1)
        with running("serve", "--port", "0", "--serial", line) as serve:
            assert serve.stdout is not None
            (said,) = read_lines(serve.stdout, 1)
            hub = re.search(r"tcp://(127\.0\.0\.1:\d+)", said)
            assert hub, said
            assert f"serial port {line} on tcp://" in said
            with running("serial", hub.group(1), line, "--pty") as relay:
                assert relay.stdout is not None
                (pty_path,) = read_lines(relay.stdout, 1)
                got = _drive(pty_path.strip())
                assert got["modes"] == [SAFE]
                assert float(got["distance"]) >= 300  # type: ignore[arg-type]
                assert float(got["angle"]) >= 90  # type: ignore[arg-type]
                relay.send_signal(signal.SIGINT)
                assert relay.wait(WAIT) == 130
            serve.send_signal(signal.SIGINT)
            assert serve.wait(WAIT) == 130
        create.send_signal(signal.SIGINT)
        assert create.wait(WAIT) == 130
