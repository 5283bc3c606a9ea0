"""``robocli connect pioneer`` and ``robocli ports``: a busy robot, JSON Lines until Ctrl-C,
rounded JSON, one unit per view (issue 7: 11, 14, 16, 18)."""

from __future__ import annotations

import json
import math
import re
import signal
import socket
import struct
import threading
from collections.abc import Iterator

import pytest

from robocli.commands._common import RESOLUTION
from robocli.devices.pioneer import Pioneer
from robocli.sim.pioneer.server import PioneerSim
from tests.commands.helpers import one_line_error, run, running


@pytest.fixture
def sim_url() -> Iterator[str]:
    with PioneerSim() as simulator:
        yield simulator.serve_tcp("127.0.0.1", 0)


def test_second_client_on_a_busy_simulator_exits_4(sim_url: str) -> None:
    with Pioneer.connect(sim_url):
        line = one_line_error(run("connect", "pioneer", sim_url, "--once"), 4)
    assert line.endswith("robot busy: another client holds it"), line


@pytest.mark.parametrize("how", ["reset", "closed"])
def test_a_reset_during_the_handshake_is_explained_as_busy(how: str) -> None:
    """A real robot's serial-to-network bridge resets or closes a second connection: no
    reason sent."""
    server = socket.create_server(("127.0.0.1", 0))

    def reset_first_connection() -> None:
        conn, _ = server.accept()
        conn.recv(16)  # the client's SYNC0
        if how == "reset":
            conn.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        conn.close()  # RST, or FIN

    thread = threading.Thread(target=reset_first_connection, daemon=True)
    thread.start()
    try:
        port = server.getsockname()[1]
        line = one_line_error(run("connect", "pioneer", f"127.0.0.1:{port}", "--once"), 4)
    finally:
        thread.join(5)
        server.close()
    assert f"was {how} during the handshake" in line, line
    assert "robot is busy: another client holds it" in line


def _decimals(value: float) -> int:
    text = repr(value)
    return len(text.split(".")[1]) if "." in text and "e" not in text else 0


def _check_rounded(data: object, digits: int = 6) -> None:
    """Every float of ``data`` has at most its field's decimals (see RESOLUTION)."""
    if isinstance(data, float):
        assert _decimals(data) <= digits, data
    elif isinstance(data, dict):
        for key, value in data.items():
            _check_rounded(value, RESOLUTION.get(key, digits))
    elif isinstance(data, list):
        for value in data:
            _check_rounded(value, digits)


def test_json_without_once_streams_one_line_per_sip_until_ctrl_c() -> None:
    with running("connect", "pioneer", "sim", "--json") as proc:
        assert proc.stdout is not None
        records = [json.loads(proc.stdout.readline()) for _ in range(4)]
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=10)
    assert proc.returncode == 130 and err.strip() == "robocli: interrupted", err
    counts = [r["state"]["sip_count"] for r in records]
    assert counts == sorted(counts) and counts[-1] > counts[0]
    for record in records:
        assert record["identity"]["subtype"] == "p3dx"
        _check_rounded(record)


def test_once_json_is_rounded_to_the_protocol_resolution() -> None:
    proc = run("connect", "pioneer", "sim", "--once", "--json")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    _check_rounded(data)
    assert all(r is None or _decimals(r) <= 3 for r in data["state"]["sonar"])


def test_text_views_turn_rates_in_deg_per_s() -> None:
    proc = run("connect", "pioneer", "sim", "--once")
    assert proc.returncode == 0, proc.stderr
    assert "deg/s" in proc.stdout and "rad" not in proc.stdout
    assert "th +0.0 deg" in proc.stdout


def test_rounding_helper_keeps_resolution_and_drops_nan() -> None:
    from robocli.commands._common import rounded

    data = rounded({"v": 0.9590000000000001, "th": math.pi, "sonar": [math.nan, 1.23456]})
    assert data == {"v": 0.959, "th": 3.1416, "sonar": [None, 1.235]}


def test_ports_lists_serial_ports() -> None:
    proc = run("ports")
    assert proc.returncode == 0 and proc.stderr == ""
    assert proc.stdout.startswith(("DEVICE", "no serial ports"))
    listed = json.loads(run("ports", "--json").stdout)
    assert isinstance(listed, list)
    assert all(set(p) == {"device", "description", "hwid"} for p in listed)
    assert all(p["device"] in proc.stdout for p in listed)


def test_connect_shows_a_simulators_laser() -> None:
    proc = run("connect", "pioneer", "sim", "--once")
    assert proc.returncode == 0, proc.stderr
    line = next(line for line in proc.stdout.splitlines() if line.startswith("laser"))
    assert re.fullmatch(r"laser\s+nearest \d+\.\d\d m at [+-]\d+ deg  \(181 readings\)", line)
    data = json.loads(run("connect", "pioneer", "sim", "--once", "--json").stdout)
    scan = data["laser"]
    assert len(scan["ranges"]) == len(scan["angles"]) == 181
    assert scan["angles"][0] == pytest.approx(-math.pi / 2, abs=1e-4)
    assert all(r is None or 0 < r < 33 for r in scan["ranges"])
    _check_rounded(data)
    plain = run("connect", "pioneer", "sim", "--once", "--no-laser")
    assert plain.returncode == 0 and "laser" not in plain.stdout


def test_the_live_view_into_a_pipe_is_one_line_per_sip() -> None:
    """Into a pipe the redrawn screen came out only after Ctrl-C: `| head -1` never ended."""
    with running("connect", "pioneer", "sim") as proc:
        assert proc.stdout is not None
        lines = [proc.stdout.readline() for _ in range(3)]
        stamps = [float(line.split()[0]) for line in lines]
        assert all(" m/s " in line and "battery" in line for line in lines), lines
        assert 0.05 < stamps[2] - stamps[0] < 0.5  # SIPs, 100 ms apart
        proc.stdout.close()
        assert proc.wait(timeout=20) == 0
