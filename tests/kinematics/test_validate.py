"""Validation: alignment recovers known delays, metrics are 0 on itself and near the noise."""

from __future__ import annotations

import numpy as np
import pytest

from robocli.kinematics import RobotModel, load_model
from robocli.kinematics.errors import ValidationError
from robocli.kinematics.trajectory import circle, ptp_joint
from robocli.kinematics.trajlog import TrajectoryLog
from robocli.kinematics.validate import shifted, validate


@pytest.fixture(scope="module")
def model() -> RobotModel:
    return load_model("irb120")


@pytest.fixture(scope="module")
def sim(model: RobotModel) -> TrajectoryLog:
    return circle(model, n=100)


def test_run_against_itself_is_zero(sim: TrajectoryLog, model: RobotModel) -> None:
    result = validate(sim, sim, model)
    assert result.delay_s == 0.0
    assert result.samples == 100
    assert np.all(result.rmse == 0) and np.all(result.mae == 0)
    assert result.tcp_max_mm == 0.0


@pytest.mark.parametrize("delay", [0.0, 0.3, 1.7, 12.5, -0.9])
def test_known_delay_is_recovered_within_one_sample(sim: TrajectoryLog, delay: float) -> None:
    dt = float(np.median(np.diff(sim.time)))
    meas = shifted(sim, delay, pad_s=2.0)
    result = validate(sim, meas)
    assert abs(result.delay_s - delay) < dt
    assert result.onset_delay_s is not None and abs(result.onset_delay_s - delay) < 2 * dt
    assert np.max(result.rmse) < 1e-6


def test_delay_recovered_from_a_differently_sampled_recording(
    sim: TrajectoryLog, model: RobotModel
) -> None:
    # a state server at 20 ms, starting 1 s before the motion, 0.45 s late
    t = np.arange(-1.0, sim.time[-1] + 1.0, 0.02)
    q = np.stack([np.interp(t, sim.time, sim.positions[:, j]) for j in range(6)], axis=1)
    meas = TrajectoryLog.from_positions(t + 0.45, q)
    result = validate(sim, meas, model)
    assert abs(result.delay_s - 0.45) < 0.02
    assert np.max(result.rmse) < 1e-3  # the recording interpolates the same path
    assert result.tcp_rmse_mm is not None and result.tcp_rmse_mm < 1.0


@pytest.mark.parametrize("sigma", [0.0005, 0.002, 0.0075])
def test_rmse_with_gaussian_noise_is_near_sigma(sim: TrajectoryLog, sigma: float) -> None:
    dt = float(np.median(np.diff(sim.time)))
    meas = shifted(sim, 0.8, pad_s=1.5, noise_rad=sigma, seed=7)
    result = validate(sim, meas)
    assert abs(result.delay_s - 0.8) < dt
    np.testing.assert_allclose(result.rmse, sigma, rtol=0.25)
    # for Gaussian noise MAE / RMSE = sqrt(2 / pi)
    np.testing.assert_allclose(np.mean(result.mae / result.rmse), np.sqrt(2 / np.pi), rtol=0.1)


def test_a_different_motion_gives_a_large_error(sim: TrajectoryLog, model: RobotModel) -> None:
    other = ptp_joint(model, np.radians([20, 20, 20, 0, 50, 0]), duration=3.0)
    result = validate(sim, other, model)
    assert np.max(result.rmse) > 0.05


def test_joint_count_mismatch_and_no_overlap(sim: TrajectoryLog) -> None:
    three = TrajectoryLog.from_positions(sim.time, sim.positions[:, :3])
    with pytest.raises(ValidationError, match="6 and 3 joints"):
        validate(sim, three)
    with pytest.raises(ValidationError, match="do not overlap"):
        validate(sim, sim, delay_s=1000.0)
