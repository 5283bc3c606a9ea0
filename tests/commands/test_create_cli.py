"""``robocli sim create`` as a user runs it: a real process, its pty or TCP port, pycreate2's
drive-and-read against it unchanged, exit codes."""

from __future__ import annotations

import json
import re
import signal
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from tests.commands.helpers import one_line_error, read_lines, run, running
from tests.paths import DATA

DRIVER = DATA / "create" / "pycreate2_drive.py"


def test_sim_create_on_a_pty_drives_pycreate2_unchanged() -> None:
    pytest.importorskip("pycreate2")
    with running("sim", "create", "--pty", "--time-scale", "2") as proc:
        assert proc.stdout is not None
        (line,) = read_lines(proc.stdout, 1)
        path = re.search(r"on (/dev/\S+)", line)
        assert path, line
        drive = subprocess.run(
            [sys.executable, str(DRIVER), path.group(1)], capture_output=True, text=True,
            timeout=120,
        )  # fmt: skip
        assert drive.returncode == 0, drive.stderr
        got = json.loads([ln for ln in drive.stdout.splitlines() if ln.startswith("{")][-1])
        assert got["distance"] >= 300 and got["angle"] >= 90 and got["modes"] == [2]
        proc.send_signal(signal.SIGINT)
        assert proc.wait(20) == 130


def test_sim_create_on_tcp_answers_sensors() -> None:
    with running("sim", "create", "--port", "0") as proc:
        assert proc.stdout is not None
        (line,) = read_lines(proc.stdout, 1)
        found = re.search(r"on tcp://([\d.]+):(\d+)", line)
        assert found, line
        with socket.create_connection((found.group(1), int(found.group(2))), timeout=10) as s:
            s.sendall(bytes([128, 142, 35]))  # start, then packet 35: the OI mode
            assert s.recv(1) == b"\x01"  # passive
        proc.send_signal(signal.SIGINT)
        assert proc.wait(20) == 130


def test_sim_create_usage_errors_are_one_line() -> None:
    assert "not both" in one_line_error(run("sim", "create", "--pty", "--port", "1"), 2)
    assert "X,Y,TH" in one_line_error(run("sim", "create", "--pose", "1,2"), 2)


def test_record_create_errors_are_one_line_and_leave_no_file(tmp_path: Path) -> None:
    out = tmp_path / "c.mcap"
    refused = run("record", "--create", "tcp://127.0.0.1:1", "-o", str(out))
    assert "connection refused" in one_line_error(refused, 3)
    with socket.socket() as silent:  # accepts, never streams
        silent.bind(("127.0.0.1", 0))
        silent.listen()
        port = silent.getsockname()[1]
        quiet = run("record", "--create", f"tcp://127.0.0.1:{port}", "-o", str(out))
    assert "no sensor stream frame" in one_line_error(quiet, 3)
    assert not out.exists()
