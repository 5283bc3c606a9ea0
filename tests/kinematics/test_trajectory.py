"""Trajectories: shapes, continuity, timing, limit checks, waypoint files."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from robocli.io.waypoints import read_waypoints
from robocli.kinematics import (
    KinematicsError,
    LimitError,
    RobotModel,
    fk,
    fk_positions,
    load_model,
)
from robocli.kinematics import trajectory as tr
from robocli.kinematics.trajlog import LogFormatError
from tests.refusals import refused


@pytest.fixture(scope="module")
def irb120() -> RobotModel:
    return load_model("irb120")


@pytest.mark.parametrize("name", ["irb120", "lrmate200id", "ur3e"])
def test_circle_is_a_continuous_circle_at_constant_orientation(name: str) -> None:
    model = load_model(name)
    log = tr.circle(model, n=100, radius=0.05)
    assert len(log) == 100
    center = fk_positions(model, model.work)[0]
    tcp = fk_positions(model, log.positions)
    np.testing.assert_allclose(log.tcp, tcp, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(tcp[:, :2] - center[:2], axis=1), 0.05, atol=1e-9)
    np.testing.assert_allclose(tcp[:, 2], center[2], atol=1e-9)
    np.testing.assert_allclose(tcp[0], tcp[-1], atol=1e-9)  # closed
    rot = fk(model, log.positions)[:, :3, :3]
    np.testing.assert_allclose(
        rot, np.broadcast_to(fk(model, model.work)[0, :3, :3], rot.shape), atol=1e-9
    )
    # no branch flip: a 3.6 deg step along the circle moves no joint by more than 3 deg
    steps = np.abs(np.diff(log.positions, axis=0))
    assert steps.max() < math.radians(3.0)


def test_circle_keeps_its_branch_on_a_fine_path(irb120: RobotModel) -> None:
    coarse = tr.circle(irb120, n=50)
    fine = tr.circle(irb120, n=400)
    # the same branch: coarse points agree with the fine path at the same angles
    np.testing.assert_allclose(
        fine.positions[::8][: len(coarse) - 1][:5], coarse.positions[:5], atol=0.05
    )
    assert np.max(np.abs(np.diff(fine.positions, axis=0))) < math.radians(1.0)


def test_constant_speed_timing(irb120: RobotModel) -> None:
    log = tr.circle(irb120, n=101, radius=0.1, speed=0.2)
    assert log.time[0] == 0.0
    length = 2 * math.pi * 0.1 * math.sin(math.pi / 100) / (math.pi / 100)
    assert log.time[-1] == pytest.approx(length / 0.2, rel=1e-12)
    step = np.linalg.norm(np.diff(log.tcp, axis=0), axis=1) / np.diff(log.time)
    np.testing.assert_allclose(step, 0.2, rtol=1e-9)


def test_duration_timing_and_rectangle_corners(irb120: RobotModel) -> None:
    log = tr.rectangle(irb120, n=33, width=0.1, height=0.06, duration=4.0)
    assert log.time[-1] == pytest.approx(4.0)
    c = fk_positions(irb120, irb120.work)[0]
    # 32 segments of 0.01 m on a 0.32 m perimeter: every corner is a sample
    for dx, dy in ((-0.05, -0.03), (0.05, -0.03), (0.05, 0.03), (-0.05, 0.03)):
        assert np.min(np.linalg.norm(log.tcp - (c + [dx, dy, 0]), axis=1)) < 1e-9


def test_ptp_joint_is_quintic_with_zero_end_speeds(irb120: RobotModel) -> None:
    goal = np.radians([30, 20, 10, 0, 40, 0])
    log = tr.ptp_joint(irb120, goal, n=201, duration=2.0)
    np.testing.assert_allclose(log.positions[0], irb120.work, atol=1e-15)
    np.testing.assert_allclose(log.positions[-1], goal, atol=1e-15)
    assert np.max(np.abs(log.velocities[[0, -1]])) < 1e-3
    # peak speed of a quintic: 15/8 of the mean
    mean = np.abs(goal - irb120.work) / 2.0
    np.testing.assert_allclose(
        np.max(np.abs(log.velocities), axis=0), 1.875 * mean, rtol=1e-3, atol=1e-9
    )


def test_ptp_cartesian_is_a_straight_line(irb120: RobotModel) -> None:
    goal = np.array([0.30, 0.10, 0.40])
    log = tr.ptp_cartesian(irb120, goal, n=50)
    p0 = fk_positions(irb120, irb120.work)[0]
    direction = (goal - p0) / np.linalg.norm(goal - p0)
    rel = log.tcp - p0
    off_line = rel - np.outer(rel @ direction, direction)
    assert np.max(np.linalg.norm(off_line, axis=1)) < 1e-9
    np.testing.assert_allclose(log.tcp[-1], goal, atol=1e-9)


def test_too_fast_names_joint_point_and_limit(irb120: RobotModel) -> None:
    with pytest.raises(LimitError, match=r"joint \d at point \d+ needs .* deg/s, over its"):
        tr.circle(irb120, duration=0.05)


def test_joint_beyond_its_range_is_named(irb120: RobotModel) -> None:
    with pytest.raises(
        LimitError, match=r"joint 3 at point \d+ is .* beyond its range \[-110, 70\]"
    ):
        tr.ptp_joint(irb120, np.radians([0, 0, 80, 0, 0, 0]), duration=5.0)


def test_speed_and_duration_together_are_refused(irb120: RobotModel) -> None:
    with pytest.raises(KinematicsError, match="not both"):
        tr.circle(irb120, speed=0.1, duration=3.0)


def test_waypoints_from_csv_and_json(irb120: RobotModel, tmp_path: Path) -> None:
    c = fk_positions(irb120, irb120.work)[0]
    pts = c + np.array([[0, 0, 0], [0.05, 0, 0], [0.05, 0.05, 0], [0, 0.05, 0.02]])
    csv_path = tmp_path / "w.csv"
    rows = [
        ",".join(repr(float(v)) for v in (t, *p)) for t, p in zip([0, 1, 2, 3.5], pts, strict=True)
    ]
    csv_path.write_text("time,x,y,z\n" + "\n".join(rows))
    wp = read_waypoints(csv_path)
    log = tr.waypoints(irb120, wp.joints, wp.points, wp.time)
    np.testing.assert_allclose(log.tcp, pts, atol=1e-9)
    np.testing.assert_allclose(log.time, [0, 1, 2, 3.5])
    js = tmp_path / "w.json"
    js.write_text(json.dumps({"joints_deg": [[0, 0, 0, 0, 0, 0], [10, 5, 5, 0, 20, 0]]}))
    wp = read_waypoints(js)
    log = tr.waypoints(irb120, wp.joints, wp.points, wp.time, duration=2.0)
    np.testing.assert_allclose(log.positions[1], np.radians([10, 5, 5, 0, 20, 0]))


@pytest.mark.parametrize(
    ("name", "text", "message"),
    [
        ("a.json", '{"points": [[0, 0, 0], [1, 2]]}', "ragged"),
        ("b.json", '{"joints": [[0, 0, 0, 0, 0, NaN], [0, 0, 0, 0, 0, 0]]}', "NaN"),
        ("c.json", '{"pts": []}', "'joints', 'joints_deg' or 'points'"),
        ("d.csv", "x,y,z\n0,0,0\n1,2\n", "line 3 has 2 values"),
        ("e.csv", "x,y,z\n0,0,zero\n", "not a number"),
        ("f.txt", "", ".json or .csv"),
        ("g.json", "{not json", "not valid JSON"),
        ("h.json", "[" * 100_000, "nested too deeply"),
    ],
)
def test_bad_waypoint_files_give_one_line(
    tmp_path: Path, name: str, text: str, message: str
) -> None:
    path = tmp_path / name
    error = refused(path, text, read_waypoints, LogFormatError, message)
    assert "\n" not in str(error) and str(path) in str(error)
