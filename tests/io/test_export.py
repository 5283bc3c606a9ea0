"""``robocli export`` and ``validate`` on a recording: recordings of the built-in simulators
read back through the exported files (CSV, JSON Lines, NPZ, the IRB120 JSON log)."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from robocli.devices.hub.client import Hub
from robocli.errors import InvalidArgument, RobocliError
from robocli.hub_server import HubServer
from robocli.io.export import arm_log, export, read_any_log
from robocli.io.record import Recorder
from robocli.kinematics.trajlog import finite_difference, read_log
from tests.io.readback import by_topic, decoded
from tests.waiting import wait_for


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "robocli", *args], capture_output=True,
                          text=True, timeout=120)  # fmt: skip


@pytest.fixture
def hub_recording(hub_server: HubServer, tmp_path: Path) -> Path:
    path = tmp_path / "hub.mcap"
    with Recorder(path) as rec, Hub.connect(f"127.0.0.1:{hub_server.port}") as hub:
        rec.add(hub)
        hub.subscribe("imu", rate=100)
        hub.subscribe("adc", rate=200, channels=0xFF)
        hub.subscribe("laser", rate=10)
        counts = {"imu": 0, "adc": 0, "laser": 0}

        def enough() -> bool:
            for name in counts:
                counts[name] += len(hub.read(name))
            return min(counts.values()) >= 3

        wait_for(enough, what="samples of imu, adc and laser")
    return path


def test_csv_one_file_per_channel(hub_recording: Path, tmp_path: Path) -> None:
    out = tmp_path / "csv"
    files = export(hub_recording, "csv", out)
    assert [f.name for f in files] == ["hub_adc.csv", "hub_imu.csv", "hub_laser.csv"]
    topics = by_topic(hub_recording)
    with (out / "hub_imu.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    items = topics["/hub/imu"]
    assert len(rows) == len(items)
    for row, item in zip(rows, items, strict=True):
        message = decoded(item)
        # t: the acquisition (publish) time, log_time the receive time, both epoch seconds
        assert float(row["t"]) == pytest.approx(item[2].publish_time / 1e9, abs=1e-6)
        assert float(row["log_time"]) == pytest.approx(item[2].log_time / 1e9, abs=1e-6)
        assert float(row["linear_acceleration.z"]) == message["linear_acceleration"]["z"]
    with (out / "hub_adc.csv").open(newline="") as fh:
        adc = next(csv.DictReader(fh))
    assert [float(adc[f"channels.{i}"]) for i in range(8)] == decoded(
        topics["/hub/adc"][0])["channels"]  # fmt: skip


def test_jsonl_and_npz(hub_recording: Path, tmp_path: Path) -> None:
    topics = by_topic(hub_recording)
    export(hub_recording, "jsonl", tmp_path / "j")
    lines = (tmp_path / "j" / "hub_laser.jsonl").read_text().splitlines()
    first = json.loads(lines[0])
    item = topics["/hub/laser"][0]
    assert len(lines) == len(topics["/hub/laser"])
    assert first["t"] == pytest.approx(item[2].publish_time / 1e9, abs=1e-6)
    assert first["ranges"] == decoded(item)["ranges"]
    export(hub_recording, "npz", tmp_path / "n")
    with np.load(tmp_path / "n" / "hub_imu.npz") as npz:
        t = npz["t"]
        z = npz["linear_acceleration.z"]
        frame = npz["frame_id"]
    imu = topics["/hub/imu"]
    assert t.dtype == np.float64 and len(t) == len(imu)
    assert t == pytest.approx([i[2].publish_time / 1e9 for i in imu], abs=1e-6)
    assert z.tolist() == [decoded(i)["linear_acceleration"]["z"] for i in imu]
    assert frame[0] == "hub/imu"
    with np.load(tmp_path / "n" / "hub_laser.npz") as npz:
        ranges = npz["ranges"]
    scans = [decoded(i)["ranges"] for i in topics["/hub/laser"]]
    assert ranges.shape == (len(scans), len(scans[0]))  # one row per scan
    assert np.array_equal(ranges, np.array(scans, dtype=float), equal_nan=True)


def test_irb120_json_is_the_recorded_feedback(arm_recording: Path,
                                              tmp_path: Path) -> None:  # fmt: skip
    path = arm_recording
    [out] = export(path, "irb120-json", tmp_path / "log")
    assert out == tmp_path / "log" / "arm.json"
    log = read_log(out)
    feedback = [decoded(i) for i in by_topic(path)["/arm/joint_feedback"]]
    assert log.positions.tolist() == [f["position"] for f in feedback]
    if feedback[0]["velocity"]:
        assert log.velocities.tolist() == [f["velocity"] for f in feedback]
    else:  # the simulator's feedback has no velocities: finite differences of the positions
        assert log.velocities == pytest.approx(finite_difference(log.time, log.positions))
    # time from 0, spaced as the controller's clock
    rt = np.array([f["robot_time"] for f in feedback])
    assert log.time[0] == 0
    assert np.diff(log.time) == pytest.approx(np.diff(rt), abs=1e-6)
    assert log.tcp is not None and log.tcp.shape == (len(feedback), 3)
    assert json.loads(out.read_text())["time_origin"] == pytest.approx(log.origin)


def test_validate_takes_a_recording(arm_recording: Path,
                                    tmp_path: Path) -> None:  # fmt: skip
    path = arm_recording
    assert read_any_log(path).positions.tolist() == arm_log(path).positions.tolist()
    [log] = export(path, "irb120-json", tmp_path)
    for args in ((str(path), str(log)), (str(log), str(path))):
        result = _run("validate", *args, "--json")
        assert result.returncode == 0, result.stderr
        report = json.loads(result.stdout)
        assert report["max_rmse_rad"] == pytest.approx(0, abs=1e-9)
        assert report["delay_s"] == pytest.approx(0, abs=1e-9)


def test_export_cli(hub_recording: Path, tmp_path: Path) -> None:
    result = _run("export", str(hub_recording), "--format", "jsonl", "-o", str(tmp_path / "o"))
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == [str(tmp_path / "o" / f"hub_{n}.jsonl")
                                     for n in ("adc", "imu", "laser")]  # fmt: skip
    bad = _run("export", str(hub_recording), "--format", "xls")
    assert bad.returncode == 2 and "--format" in bad.stderr
    none = _run("export", str(hub_recording), "--format", "irb120-json", "-o", str(tmp_path))
    assert none.returncode == 1 and "no arm joint states" in none.stderr


def test_export_refusals(tmp_path: Path) -> None:
    text = tmp_path / "x.mcap"
    text.write_text("not a recording")
    with pytest.raises(RobocliError, match="not an MCAP file"):
        export(text, "csv", tmp_path)
    with pytest.raises(InvalidArgument):
        export(text, "xls", tmp_path)
