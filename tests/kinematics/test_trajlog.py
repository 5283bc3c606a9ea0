"""Trajectory logs: the paper's JSON layout, CSV and NPZ by suffix, and malformed files."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import robocli.kinematics.trajlog as trajlog
from robocli.errors import EXIT_USAGE
from robocli.kinematics import load_model
from robocli.kinematics.trajectory import circle
from robocli.kinematics.trajlog import LogFormatError, TrajectoryLog, read_log, write_log


@pytest.fixture(scope="module")
def log() -> TrajectoryLog:
    return circle(load_model("irb120"), n=30)


@pytest.mark.parametrize("suffix", [".json", ".csv", ".npz"])
def test_round_trip_by_suffix_is_exact(log: TrajectoryLog, tmp_path: Path, suffix: str) -> None:
    back = read_log(write_log(log, tmp_path / f"run{suffix}"))
    for a, b in (
        (log.time, back.time),
        (log.positions, back.positions),
        (log.velocities, back.velocities),
        (log.tcp, back.tcp),
    ):
        np.testing.assert_array_equal(a, b)


def test_json_is_the_paper_layout(log: TrajectoryLog, tmp_path: Path) -> None:
    doc = json.loads(write_log(log, tmp_path / "sim.json").read_text())
    assert set(doc) == {"time", "joints_positions", "joints_velocities", "tcp"}
    assert len(doc["time"]) == 30
    assert all(len(r) == 6 for r in doc["joints_positions"] + doc["joints_velocities"])
    assert all(len(r) == 3 for r in doc["tcp"])


def test_measured_log_without_velocities_or_tcp(tmp_path: Path) -> None:
    path = tmp_path / "real.json"
    path.write_text(
        json.dumps({"time": [0.0, 0.5, 1.0], "joints_positions": [[0.0] * 6, [0.5] * 6, [1.0] * 6]})
    )
    got = read_log(path)
    np.testing.assert_allclose(got.velocities, 1.0)
    assert got.tcp is None


GOOD = {"time": [0.0, 0.1], "joints_positions": [[0.0] * 6, [0.1] * 6]}


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('{"time": [0, 0.1]}', "missing key 'joints_positions'"),
        ('{"time": [0, NaN], "joints_positions": [[0], [0]]}', "NaN"),
        ('{"time": [0, 0.1], "joints_positions": [[0, 0], [0]]}', "row 1 has 1 values"),
        ('{"time": [0, 0.1, 0.2], "joints_positions": [[0], [0]]}', "2 samples but 'time' has 3"),
        ('{"time": [0, 0], "joints_positions": [[0], [0]]}', "'time' does not increase at sample"),
        ('{"time": [0, 1e400], "joints_positions": [[0], [0]]}', "NaN or an infinity"),
        ('{"time": [0, "a"], "joints_positions": [[0], [0]]}', "not a number"),
        ("[1, 2]", "a JSON object"),
        ('{"time": [0, 0.1', "not valid JSON"),
        ('{"time": [0, 0.1], "joints_positions": [[0], [0]], "tcp": [[0, 0], [0, 0]]}', "tcp"),
        ("[" * 100_000, "nested too deeply"),
    ],
)
def test_malformed_json_gives_one_typed_line(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "bad.json"
    path.write_text(text)
    with pytest.raises(LogFormatError, match=message) as info:
        read_log(path)
    assert info.value.exit_code == EXIT_USAGE
    assert "\n" not in str(info.value) and str(path) in str(info.value)


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("bad.csv", b"time,q1,q2\n0,0,0\n0.1,0\n", "line 3 has 2 values"),
        ("bad2.csv", b"t,q1\n0,0\n", "starts with a header"),
        ("bad3.csv", b"time,q1\n0,nan\n0.1,0\n", "NaN"),
        ("bad.npz", b"PK\x03\x04 not a zip", "not a valid NPZ"),
        ("bad.txt", b"{}", "unknown log suffix"),
    ],
)
def test_malformed_csv_npz_and_suffix(
    tmp_path: Path, name: str, content: bytes, message: str
) -> None:
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(LogFormatError, match=message):
        read_log(path)


def test_npz_missing_array(tmp_path: Path) -> None:
    path = tmp_path / "x.npz"
    np.savez(path, time=np.arange(3.0))
    with pytest.raises(LogFormatError, match="missing array 'joints_positions'"):
        read_log(path)


def test_oversized_log_is_refused_before_parsing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "big.json"
    path.write_text(json.dumps(GOOD) + " " * 5000)
    monkeypatch.setattr(trajlog, "MAX_LOG_BYTES", 4096)
    with pytest.raises(LogFormatError, match="over the 0 MiB log limit"):
        read_log(path)
    monkeypatch.undo()
    assert len(read_log(path)) == 2


def test_a_log_without_end_is_read_in_bounded_memory(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``stat`` gives no size for a device or a pipe: the read itself is capped."""
    path = tmp_path / "zero.json"
    path.symlink_to("/dev/zero")
    monkeypatch.setattr(trajlog, "MAX_LOG_BYTES", 1 << 16)
    with pytest.raises(LogFormatError, match="over the 0 MiB limit"):
        read_log(path)


def test_missing_file_is_a_usage_error(tmp_path: Path) -> None:
    with pytest.raises(LogFormatError, match="cannot read"):
        read_log(tmp_path / "nope.json")


def test_npz_zip_bomb_refused_before_decompressing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The limit applies to what the members expand to, not to the compressed file."""
    path = tmp_path / "bomb.npz"
    n = 1 << 19  # 4 MiB of float64 zeros, deflated to a few KiB
    np.savez_compressed(path, time=np.zeros(n), joints_positions=np.zeros((n, 1)))
    assert path.stat().st_size < 64 * 1024
    monkeypatch.setattr(trajlog, "MAX_LOG_BYTES", 1 << 20)
    with pytest.raises(LogFormatError, match=r"time\.npy expands to 4194432 bytes, over the 1 MiB"):
        read_log(path)


@pytest.mark.parametrize(("dtype", "kind"), [(complex, "complex numbers"), (bool, "booleans"),
                                             ("U3", "text")])  # fmt: skip
def test_npz_of_non_real_numbers_is_refused(tmp_path: Path, dtype: object, kind: str) -> None:
    path = tmp_path / "c.npz"
    np.savez(path, time=np.arange(3.0), joints_positions=np.ones((3, 6)).astype(dtype))
    with pytest.raises(LogFormatError, match=f"'joints_positions' holds {kind}: logs hold real"):
        read_log(path)


@pytest.mark.parametrize("suffix", [".json", ".npz"])
def test_time_origin_round_trip(log: TrajectoryLog, tmp_path: Path, suffix: str) -> None:
    from dataclasses import replace

    path = write_log(replace(log, origin=16989.326389693), tmp_path / f"r{suffix}")
    assert read_log(path).origin == 16989.326389693
    assert read_log(write_log(log, tmp_path / f"s{suffix}")).origin is None


def test_bad_time_origin(tmp_path: Path) -> None:
    path = tmp_path / "o.json"
    path.write_text(json.dumps({**GOOD, "time_origin": [1, 2]}))
    with pytest.raises(LogFormatError, match="'time_origin' must be one number"):
        read_log(path)


def test_corrupt_csv_and_npz_bytes_give_one_typed_line(log: TrajectoryLog, tmp_path: Path) -> None:
    """Found by the file-readers fuzz target: a bare CR inside a CSV field (csv.Error) and an
    NPZ member whose deflate stream is corrupt (zlib.error) escaped as untyped errors."""
    from robocli.io.waypoints import read_waypoints

    bad = tmp_path / "cr.csv"
    bad.write_bytes(b"time,q1\n0\r1,0\n")
    with pytest.raises(LogFormatError, match="not a valid CSV log"):
        read_log(bad)
    with pytest.raises(LogFormatError, match="not valid CSV"):
        read_waypoints(bad)
    path = write_log(log, tmp_path / "log.npz")
    data = bytearray(path.read_bytes())
    start = data.index(b"time.npy") + len(b"time.npy")  # the first member's deflated bytes
    for i in range(start, start + 40):
        data[i] ^= 0x5A
    path.write_bytes(bytes(data))
    with pytest.raises(LogFormatError, match="NPZ"):
        read_log(path)
