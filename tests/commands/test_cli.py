"""The CLI as a user runs it: real processes, exit codes, one-line errors, JSON output."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from robocli.devices.pioneer import Pioneer
from tests import paths
from tests.commands.helpers import one_line_error, read_lines, run

DATA = paths.DATA / "arcos"


def test_help_and_version() -> None:
    proc = run("--help")
    assert proc.returncode == 0 and "connect" in proc.stdout and "bench" in proc.stdout
    from robocli import __version__

    assert run("--version").stdout.strip() == f"robocli {__version__}"


def test_version_is_the_installed_distributions() -> None:
    """The version comes from the installed robocli-robots (setuptools-scm took it from the git
    tag at install time), not from a number written in the source."""
    from importlib.metadata import version

    assert run("--version").stdout.strip() == f"robocli {version('robocli-robots')}"


@pytest.mark.parametrize(
    "args",
    [
        ("connect", "pioneer"),  # missing PORT
        ("bench", "rtt", "--count", "x"),  # not a number
        ("bench", "rtt", "--target", "toaster"),  # unknown target
        ("sim", "pioneer", "--sip-ms", "0"),  # out of range
        ("sim", "pioneer", "--subtype", "box"),  # no parameters for it
        ("dump", "pioneer"),  # neither PORT nor --file
        ("teleop", "pioneer", "sim"),  # stdin is not a terminal
        ("frobnicate",),
    ],
)
def test_usage_errors_exit_2_with_one_line(args: tuple[str, ...]) -> None:
    one_line_error(run(*args), 2)


def test_unreachable_robot_exits_3() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        line = one_line_error(run("connect", "pioneer", f"tcp://127.0.0.1:{s.getsockname()[1]}"), 3)
    assert "connection refused" in line


def test_silent_port_exits_3_after_handshake_timeout() -> None:
    """Like trace f (a stale AMRISim port): TCP accepts, no byte ever comes back."""
    srv = socket.create_server(("127.0.0.1", 0))
    held: list[socket.socket] = []
    threading.Thread(target=lambda: held.append(srv.accept()[0]), daemon=True).start()
    try:
        port = srv.getsockname()[1]
        line = one_line_error(run("connect", "pioneer", f"127.0.0.1:{port}", "--timeout", "1"), 3)
        assert "no robot answering" in line
    finally:
        srv.close()
        for conn in held:
            conn.close()


def test_connect_once_json_against_embedded_sim() -> None:
    proc = run("connect", "pioneer", "sim", "--once", "--json")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["identity"]["subtype"] == "p3dx" and data["identity"]["type"] == "Pioneer"
    assert data["state"]["motors_enabled"] is False  # motors stay off until ENABLE
    assert len(data["state"]["sonar"]) == 16 and data["link"]["bad_checksums"] == 0


def test_dump_a_recorded_capture() -> None:
    proc = run("dump", "pioneer", "--file", str(DATA / "a_simpleConnect.jsonl"), "-n", "9", "--hex")
    assert proc.returncode == 0, proc.stderr
    names = [line.split()[2] for line in proc.stdout.splitlines() if "->" in line or "<-" in line]
    assert names == [
        "SYNC0",
        "SYNC0-reply",
        "SYNC1",
        "SYNC1-reply",
        "SYNC2",
        "SYNC2-reply",
        "OPEN",
        "CONFIG",
        "CONFIG",
    ]
    assert "fa fb 06 01 3b 01 00 02 3b" in proc.stdout  # OPEN int 1, byte for byte


def test_bench_rtt_json_reports_floor_multiples() -> None:
    proc = run("bench", "rtt", "-n", "30", "--floor-n", "200", "--json")
    assert proc.returncode == 0, proc.stderr
    stages = {row["name"]: row for row in json.loads(proc.stdout)}
    floor, client = stages["C floor, same CPU"], stages["client vs C responder"]
    assert floor["n"] == 200 and client["n"] == 30
    assert 0 < floor["median"] and client["x_floor_median"] == pytest.approx(
        client["median"] / floor["median"], rel=2e-3
    )  # JSON is rounded to 3 decimals


def test_sim_server_serves_until_sigterm() -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "robocli", "sim", "pioneer", "--port", "0", "--robots", "2"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        urls = [proc.stdout.readline().split(" on ")[1].strip() for _ in range(2)]
        assert urls[0] != urls[1]
        for url in urls:
            with Pioneer.connect(url) as robot:
                assert robot.identity.subtype == "p3dx"
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=10) == 130  # interrupted, as every command
    finally:
        if proc.poll() is None:
            os.kill(proc.pid, signal.SIGKILL)


def test_live_view_runs_until_interrupted() -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "robocli", "connect", "pioneer", "sim"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        first = read_lines(proc.stdout, 10)  # into a pipe: one line per SIP (panel: test_screens)
        assert len(first) == 10, first
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=30)
        assert proc.returncode == 130 and err.strip() == "robocli: interrupted"
        lines = first + out.splitlines()
        assert all(" m/s " in line and "battery" in line for line in lines), lines
    finally:
        if proc.poll() is None:
            proc.kill()


def test_sim_reports_a_bad_map_and_a_busy_port(tmp_path: Path) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text('{"walls": [[0, 0, 1]]}')
    assert "wall 0" in one_line_error(run("sim", "pioneer", "--map", str(bad)), 2)
    with socket.create_server(("127.0.0.1", 0)) as busy:
        port = str(busy.getsockname()[1])
        assert "in use" in one_line_error(run("sim", "pioneer", "--port", port), 1)
