"""robocli.kinematics.files as a script calls it: a trajectory written and summarised, a
log compared with itself."""

from __future__ import annotations

from pathlib import Path

from robocli.io.compare import compare_files
from robocli.kinematics import load_model
from robocli.kinematics.files import write_trajectory
from robocli.kinematics.trajectory import circle


def test_write_then_compare(tmp_path: Path) -> None:
    model = load_model("irb120")
    log = circle(model, 50, 0.03, duration=2.0)
    summary = write_trajectory(model, log, "circle", tmp_path / "sim.json")
    assert summary["points"] == 50 and summary["duration_s"] == 2.0
    assert 0 < summary["max_speed_fraction"] < 1 and 1 <= summary["max_speed_joint"] <= 6
    result = compare_files(tmp_path / "sim.json", tmp_path / "sim.json")
    assert result.rmse.max() < 1e-9
