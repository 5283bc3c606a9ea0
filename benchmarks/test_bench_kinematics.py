"""Benchmarks of the arm kinematics (pytest-benchmark).

Targets (shared/targets.md): IRB120 forward kinematics >= 1 M poses/s vectorised (Robotics
Toolbox for Python's DH ``fkine``: ~224 us per pose); IK of a 100-point circle <= 50 ms in
total with a continuous branch (rtb ``ikine_LM``: ~5.8 ms per pose).

The per-pose Python loop (a textbook product of six 4x4 DH matrices, as a script without
vectorisation would write it) is measured in the same run, and the vectorised figure is
reported as a ratio to it. Robotics Toolbox is measured too when it is installed (it is not
a dependency).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from robocli.kinematics import fk, fk_positions, ik_path, load_model
from robocli.kinematics.model import RobotModel
from robocli.kinematics.trajectory import circle, circle_path
from tests.kinematics.dh import dh_product

N_FK = 1_000_000
N_LOOP = 2_000
_RATES: dict[str, float] = {}


@pytest.fixture(scope="module")
def irb120() -> RobotModel:
    return load_model("irb120")


@pytest.fixture(scope="module")
def poses(irb120: RobotModel) -> np.ndarray:
    rng = np.random.default_rng(0)
    return rng.uniform(irb120.limits[:, 0], irb120.limits[:, 1], (N_FK, 6))


def _dh_loop(model: RobotModel, q: np.ndarray) -> np.ndarray:
    """The per-pose loop: tests' textbook DH product, one pose at a time."""
    return np.stack([dh_product(model, row) for row in q])


def _rate(benchmark: Any, count: int, key: str) -> float:
    rate = count / float(benchmark.stats.stats.mean)
    benchmark.extra_info[key] = rate
    _RATES[key] = rate
    return rate


def test_fk_per_pose_python_loop(benchmark: Any, irb120: RobotModel, poses: np.ndarray) -> None:
    """Baseline: one pose at a time, six 4x4 matrix products in Python."""
    q = poses[:N_LOOP]
    out = benchmark.pedantic(lambda: _dh_loop(irb120, q), rounds=3, iterations=1)
    np.testing.assert_allclose(out, fk(irb120, q), atol=1e-12)
    _rate(benchmark, N_LOOP, "loop_poses_per_s")


def test_fk_positions_vectorised(benchmark: Any, irb120: RobotModel, poses: np.ndarray) -> None:
    """1 M poses -> 1 M x 3 flange positions."""
    out = benchmark.pedantic(
        lambda: fk_positions(irb120, poses), rounds=5, iterations=1, warmup_rounds=1
    )
    assert out.shape == (N_FK, 3)
    rate = _rate(benchmark, N_FK, "poses_per_s")
    if "loop_poses_per_s" in _RATES:
        benchmark.extra_info["x_loop"] = rate / _RATES["loop_poses_per_s"]


def test_fk_matrices_vectorised(benchmark: Any, irb120: RobotModel, poses: np.ndarray) -> None:
    """1 M poses -> 1 M x 4 x 4 homogeneous matrices."""
    out = benchmark.pedantic(lambda: fk(irb120, poses), rounds=5, iterations=1, warmup_rounds=1)
    assert out.shape == (N_FK, 4, 4)
    rate = _rate(benchmark, N_FK, "poses_per_s")
    if "loop_poses_per_s" in _RATES:
        benchmark.extra_info["x_loop"] = rate / _RATES["loop_poses_per_s"]


def test_fk_robotics_toolbox(benchmark: Any, irb120: RobotModel, poses: np.ndarray) -> None:
    """Robotics Toolbox for Python's DH fkine, one pose per call (when installed)."""
    rtb = pytest.importorskip("roboticstoolbox")
    links = [
        rtb.RevoluteDH(a=irb120.a[i], d=irb120.d[i], alpha=irb120.alpha[i], offset=irb120.offset[i])
        for i in range(6)
    ]
    robot = rtb.DHRobot(links, name="irb120")
    q = poses[:N_LOOP]
    out = benchmark.pedantic(lambda: [robot.fkine(row).A for row in q], rounds=3, iterations=1)
    np.testing.assert_allclose(np.stack(out), fk(irb120, q), atol=1e-12)
    _rate(benchmark, N_LOOP, "rtb_poses_per_s")


def test_ik_circle_100_points(benchmark: Any, irb120: RobotModel) -> None:
    """Closed-form IK of a 100-point circle, branch chosen point by point."""
    start = fk(irb120, irb120.work)[0]
    targets = np.repeat(start[None], 100, axis=0)
    targets[:, :3, 3] = circle_path(start[:3, 3], 0.05, 100)
    q = benchmark(lambda: ik_path(irb120, targets, irb120.work))
    np.testing.assert_allclose(fk(irb120, q), targets, atol=1e-9)
    assert np.max(np.abs(np.diff(q, axis=0))) < math.radians(3)
    benchmark.extra_info["ms_per_circle"] = float(benchmark.stats.stats.mean) * 1e3


def test_traj_circle_end_to_end(benchmark: Any, irb120: RobotModel) -> None:
    """The whole `traj circle`: path, IK, timing, finite differences, FK, limit checks."""
    log = benchmark(lambda: circle(irb120, n=100))
    assert len(log) == 100
    benchmark.extra_info["ms_per_circle"] = float(benchmark.stats.stats.mean) * 1e3


def test_ik_circle_ur3e_damped_least_squares(benchmark: Any) -> None:
    """UR3e (no spherical wrist): damped least squares seeded from the previous point."""
    ur3e = load_model("ur3e")
    log = benchmark.pedantic(lambda: circle(ur3e, n=100), rounds=3, iterations=1)
    assert len(log) == 100
    benchmark.extra_info["ms_per_circle"] = float(benchmark.stats.stats.mean) * 1e3
