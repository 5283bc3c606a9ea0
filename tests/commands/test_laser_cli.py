"""``robocli connect|sim|dump laser`` and ``bench jitter --target laser`` as a user runs
them: real processes, exit codes, SI JSON."""

from __future__ import annotations

import json
import math
import re
import signal
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from robocli import Laser
from robocli.sim.hokuyo import HokuyoSim
from tests.commands.helpers import one_line_error, read_lines, run, running
from tests.waiting import wait_for


@pytest.fixture
def sim_url() -> Iterator[str]:
    with HokuyoSim("ust-10lx", time_scale=2.0) as sim:
        yield sim.serve_tcp()


def test_connect_sim_once_json_is_si() -> None:
    proc = run("connect", "laser", "sim", "--once", "--json")
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    assert data["identity"]["model"] == "UTM-30LX"
    assert len(data["ranges"]) == len(data["angles"]) == 1081
    assert data["angles"][0] == pytest.approx(-3 * math.pi / 4, abs=1e-6)
    assert data["angles"][540] == 0.0
    valid = [r for r in data["ranges"] if r is not None]
    assert valid and all(0.023 <= r <= 60.0 for r in valid)  # metres, not mm
    assert abs(data["t"] - data["received"]) < 1.0 and data["t"] > 1.6e9  # Unix epoch


def test_connect_jsonl_streams_scans_of_a_step_range(sim_url: str) -> None:
    proc = run("connect", "laser", sim_url, "--json", "-n", "3",
               "--start", "530", "--end", "550", "--cluster", "3")  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    lines = [json.loads(line) for line in proc.stdout.splitlines()]
    assert len(lines) == 3
    assert all(len(s["ranges"]) == 7 for s in lines)
    assert [s["stamp_ms"] for s in lines] == sorted({s["stamp_ms"] for s in lines})


def test_connect_text_shows_identity_then_scans(sim_url: str) -> None:
    proc = run("connect", "laser", sim_url, "-n", "2")
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout.splitlines()
    assert out[0].startswith("UST-10LX serial H0000002 on tcp://")
    assert "270" in out[2] or "-135.0 .. 135.0 deg" in out[2]
    assert len(out) == 5 and all("valid" in line for line in out[3:])


def test_connect_errors_are_one_line_with_exit_codes() -> None:
    assert "is not one of 'urg-04lx'" in one_line_error(
        run("connect", "laser", "sim", "--model", "x"), 2
    )
    assert "refused" in one_line_error(run("connect", "laser", "tcp://127.0.0.1:1"), 3)
    assert "-f" in one_line_error(run("connect", "laser", "sim", "-f", "xml"), 2)  # now --json


def test_sim_laser_over_a_pty_serves_the_client() -> None:
    with running("sim", "laser", "--model", "urg-04lx", "--pty") as proc:
        assert proc.stdout is not None
        (line,) = read_lines(proc.stdout, 1)
        path = re.search(r"on (/dev/\S+)", line)
        assert path, line
        with Laser.connect(path.group(1)) as laser:
            assert laser.switched and laser.scan().ranges.size == 682
        proc.send_signal(signal.SIGINT)
        assert proc.wait(20) == 130


def test_dump_laser_shows_every_line_both_ways_decoded(sim_url: str, tmp_path: Path) -> None:
    proc = run("dump", "laser", sim_url, "-n", "1")
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    assert re.search(r"-> QT\s+QT", out) and re.search(r"<- 00P\s+status 00: ok, sum ok", out)
    assert re.search(r"<- DMAX:30000;.\s+DMAX = 30000, sum ok", out)
    assert re.search(r"-> MD0000108001000\s+MD start 0 end 1080 cluster 1", out)
    assert "timestamp" in out and "data 1/" in out and "= MD 1081 values" in out
    capture = tmp_path / "laser.jsonl"
    g8 = b"GD0384038601\n00P\n00?Xg\n0?X1Dh000d\n\n"
    capture.write_text(
        json.dumps({"t": 0.0, "dir": "c2s", "hex": b"GD0384038601\n".hex()}) + "\n"
        + json.dumps({"t": 0.01, "dir": "s2c", "hex": g8.hex()}) + "\n"
    )  # fmt: skip
    proc = run("dump", "laser", "--file", str(capture), "--json")
    assert proc.returncode == 0, proc.stderr
    rows = [json.loads(line) for line in proc.stdout.splitlines()]
    assert rows[0]["dir"] == "c2s" and rows[0]["what"] == "GD start 384 end 386 cluster 1"
    assert rows[-1]["what"].startswith("= GD 3 values, steps 384..386")
    junk = tmp_path / "junk.bin"
    junk.write_bytes(b"\x00" * 100)
    assert "no SCIP line" in one_line_error(run("dump", "laser", "--file", str(junk)), 1)


def test_bench_jitter_laser_reports_the_scan_period(sim_url: str) -> None:
    proc = run("bench", "jitter", "--target", "laser", sim_url, "-n", "20", "--json")
    assert proc.returncode == 0, proc.stderr
    names = json.dumps(json.loads(proc.stdout))
    assert "scan period (stamped)" in names and "decode one frame" in names


def test_ctrl_c_on_connect_stops_the_stream_with_qt() -> None:
    with HokuyoSim("urg-04lx", time_scale=2.0) as sim:
        path = sim.serve_pty()
        with running("connect", "laser", path) as proc:
            assert proc.stdout is not None
            lines = read_lines(proc.stdout, 5)
            assert len(lines) == 5 and "valid" in lines[-1]
            (session,) = sim.sessions()
            assert session.stream is not None
            proc.send_signal(signal.SIGINT)
            assert proc.wait(20) == 130
        wait_for(lambda: session.stream is None, "the stream stopped")
        assert session.stream is None and not session.laser  # QT went out before the exit


def test_dump_file_reads_in_bounded_memory_and_gives_up_on_noise(tmp_path: Path) -> None:
    capture = tmp_path / "long.jsonl"
    with capture.open("w") as f:  # a 3 MB line that is no record, then a session
        f.write("x" * 3_000_000 + "\n")
        f.write(json.dumps({"t": 0.0, "dir": "c2s", "hex": b"VV\n".hex()}) + "\n")
        f.write(json.dumps({"t": 0.1, "dir": "s2c", "hex": b"VV\n00P\nVEND:Hokuyo;x\n\n".hex()}))
    proc = run("dump", "laser", "--file", str(capture))
    assert proc.returncode == 0, proc.stderr
    assert "VEND = Hokuyo, BAD SUM" in proc.stdout  # the sum of "VEND:Hokuyo" is not 'x'
    assert "16 MiB without a SCIP block" in one_line_error(
        run("dump", "laser", "--file", "/dev/zero"), 1
    )


def test_connect_pioneer_with_a_hokuyo_sim_places_its_scan() -> None:
    """`connect pioneer sim --laser sim`: the Hokuyo (18 mm ahead of a P3-DX at the default
    room's start) reads 7.982 m to the wall at x = 8 straight ahead: (8, 0) in odom."""
    proc = run("connect", "pioneer", "sim", "--laser", "sim", "--once", "--json", timeout=90)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    h = data["hokuyo"]
    ahead = h["angles"].index(0.0)
    assert h["ranges"][ahead] == pytest.approx(7.982, abs=0.0015)
    assert h["points_robot"][ahead] == pytest.approx([8.0, 0.0], abs=0.0015)
    assert h["points_odom"][ahead] == pytest.approx([8.0, 0.0], abs=0.0015)
    assert h["mount"] == {"x": 0.018, "y": 0.0, "th": 0.0, "flipped": False}
    assert h["pose"] == {"x": 0.0, "y": 0.0, "th": 0.0}
    assert len(h["ranges"]) == len(h["angles"]) == len(h["points_odom"]) == 1081
    assert abs(h["t"] - time.time()) < 600  # Unix epoch
    assert "laser" in data  # the simulator's own (ARCOS) laser still starts by default


def test_connect_pioneer_laser_text_jsonl_and_usage(sim_url: str) -> None:
    proc = run("connect", "pioneer", "sim", "--laser", sim_url, "--once", "--no-laser",
               timeout=90)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert re.search(r"^hokuyo +nearest .* odom \(", proc.stdout, re.M), proc.stdout
    assert "\nlaser " not in proc.stdout  # --no-laser: no ARCOS laser
    with running("connect", "pioneer", "sim", "--laser", "sim", "--json") as p:
        assert p.stdout is not None
        deadline = time.monotonic() + 30
        while True:
            line = json.loads(p.stdout.readline())
            if "hokuyo" in line:
                break
            assert time.monotonic() < deadline
        assert len(line["hokuyo"]["points_odom"]) == 1081
        p.send_signal(signal.SIGINT)
        assert p.wait(30) == 130
    bad = run("connect", "pioneer", "sim", "--once", "--laser")
    assert bad.returncode == 2 and "--laser" in bad.stderr


@pytest.mark.parametrize("command", ["connect", "dump"])
def test_a_sensor_that_ignores_the_closing_qt_is_one_line_and_exit_3(command: str) -> None:
    """The stop at the end of the stream runs in the command, not at garbage collection
    (which printed an 18-line "Exception ignored in generator" and exited 0)."""
    with HokuyoSim("ust-10lx", time_scale=2.0) as sim:
        sim.ignore_qt = True  # QT while streaming: no reply, the stream goes on
        proc = run(command, "laser", sim.serve_tcp(), "-n", "2", "--timeout", "0.3")
    assert "did not answer QT" in one_line_error(proc, 3)
    assert "Exception ignored" not in proc.stderr


def test_a_held_simulator_refuses_a_second_client_with_exit_4(sim_url: str) -> None:
    """The first client keeps asking for scans (a client in use, whatever idle limit the
    server keeps) while a second one connects: exit 4, one line, not "link lost" (exit 1)."""
    done = threading.Event()
    scans = []
    with Laser.connect(sim_url, sync_samples=0) as first:

        def use() -> None:
            while not done.is_set():
                scans.append(first.scan())

        user = threading.Thread(target=use, daemon=True)
        user.start()
        try:
            proc = run("connect", "laser", sim_url, "--once")
        finally:
            done.set()
            user.join(30)
    assert "laser busy" in one_line_error(proc, 4)
    assert scans and not user.is_alive()  # the first client was served throughout
