"""FK against a per-pose DH product, the Jacobian against finite differences, IK round trips,
branch choice and unreachable targets."""

from __future__ import annotations

import math

import numpy as np
import pytest

from robocli.errors import EXIT_USAGE
from robocli.kinematics import (
    UnreachableError,
    analytic_solutions,
    fk,
    fk_positions,
    ik,
    ik_path,
    jacobian,
    load_model,
)
from robocli.kinematics.model import RobotModel
from tests.kinematics.dh import dh_product

ALL = ["irb120", "ur3e", "lrmate200id"]


def _random_q(model: RobotModel, n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(model.limits[:, 0], model.limits[:, 1], (n, 6))


@pytest.mark.parametrize("name", ALL)
def test_vectorised_fk_equals_the_per_pose_dh_product(name: str) -> None:
    model = load_model(name)
    q = _random_q(model, 300, 1)
    want = np.stack([dh_product(model, row) for row in q])
    np.testing.assert_allclose(fk(model, q), want, rtol=0, atol=1e-13)
    np.testing.assert_allclose(fk_positions(model, q), want[:, :3, 3], rtol=0, atol=1e-13)


@pytest.mark.parametrize("name", ALL)
def test_jacobian_matches_finite_differences(name: str) -> None:
    model = load_model(name)
    for q in _random_q(model, 5, 2):
        jac = jacobian(model, q)
        assert jac.shape == (6, 6)
        h = 1e-7
        t0 = fk(model, q)[0]
        for i in range(6):
            dq = np.zeros(6)
            dq[i] = h
            t1 = fk(model, q + dq)[0]
            lin = (t1[:3, 3] - t0[:3, 3]) / h
            skew = (t1[:3, :3] @ t0[:3, :3].T - np.eye(3)) / h
            ang = np.array([skew[2, 1], skew[0, 2], skew[1, 0]])
            np.testing.assert_allclose(jac[:3, i], lin, atol=1e-6)
            np.testing.assert_allclose(jac[3:, i], ang, atol=1e-6)


@pytest.mark.parametrize(("name", "count"), [("irb120", 500), ("lrmate200id", 500), ("ur3e", 40)])
def test_random_fk_ik_fk_round_trips_to_1e_9(name: str, count: int) -> None:
    model = load_model(name)
    q = _random_q(model, count, 3)
    targets = fk(model, q)
    worst = 0.0
    for k in range(count):
        # seeds far from the answer: the home pose for half of them
        seed = model.home if k % 2 else q[k] + 0.3
        sol = ik(model, targets[k], seed)
        assert np.all(model.within_limits(sol))
        worst = max(worst, float(np.max(np.abs(fk(model, sol)[0] - targets[k]))))
    assert worst < 1e-9


@pytest.mark.parametrize("name", ["irb120", "lrmate200id"])
def test_every_closed_form_branch_reaches_the_target(name: str) -> None:
    model = load_model(name)
    targets = fk(model, _random_q(model, 100, 4))
    sols, valid = analytic_solutions(model, targets)
    assert sols.shape == (100, 8, 6)
    assert valid.mean() > 0.8
    back = fk(model, sols.reshape(-1, 6)).reshape(100, 8, 4, 4)
    err = np.max(np.abs(back - targets[:, None]), axis=(2, 3))
    assert np.max(err[valid]) < 1e-9
    # distinct branches: shoulder, elbow and wrist configurations differ
    assert np.all(np.ptp(sols[valid.all(axis=1)][:, :, 2], axis=1) > 1e-6)


def test_ik_picks_the_branch_of_the_previous_pose() -> None:
    model = load_model("irb120")
    q_ref = np.radians([20, 30, -40, 50, 60, -70])
    target = fk(model, q_ref)[0]
    np.testing.assert_allclose(ik(model, target, q_ref + 0.01), q_ref, atol=1e-9)
    # another branch (wrist flipped) is chosen when the previous pose sits on it
    flipped = q_ref + np.array([0, 0, 0, -math.pi, 0, math.pi])  # q4 -130, q6 110 deg
    flipped[4] = -q_ref[4]
    sol = ik(model, target, flipped)
    np.testing.assert_allclose(fk(model, sol)[0], target, atol=1e-9)
    np.testing.assert_allclose(sol, flipped, atol=1e-9)


def test_wrist_singularity_keeps_joint_4_and_reaches_the_pose() -> None:
    model = load_model("irb120")
    q_ref = np.radians([10, 20, 10, 0, 0, 30])  # q5 = 0: axes 4 and 6 aligned
    target = fk(model, q_ref)[0]
    prev = np.radians([10, 20, 10, 25, 1, 30])
    sol = ik(model, target, prev)
    np.testing.assert_allclose(fk(model, sol)[0], target, atol=1e-9)
    assert sol[3] == pytest.approx(prev[3], abs=1e-12)


@pytest.mark.parametrize("name", ["irb120", "ur3e"])
def test_unreachable_point_names_its_index_and_position(name: str) -> None:
    model = load_model(name)
    poses = np.repeat(fk(model, model.work), 5, axis=0)
    poses[3, :3, 3] = [2.0, 0.5, 0.3]
    with pytest.raises(UnreachableError) as info:
        ik_path(model, poses)
    err = info.value
    assert err.index == 3 and err.position == pytest.approx((2.0, 0.5, 0.3))
    assert "point 3" in str(err) and "(2.0000, 0.5000, 0.3000) m" in str(err)
    assert err.exit_code == EXIT_USAGE and isinstance(err, ValueError)


def test_target_reachable_only_beyond_joint_limits_says_so() -> None:
    model = load_model("irb120")
    q = np.radians([0, -100, -100, 0, 0, 0])  # a pose in reach, q3 at -100 is fine
    target = fk(model, q)[0]
    target[:3, 3] = [0.0, 0.0, -0.25]  # under the base: only past joint 2/3 limits
    with pytest.raises(UnreachableError, match="joint limits|outside the workspace"):
        ik(model, target)


def test_nan_target_is_refused() -> None:
    model = load_model("irb120")
    target = fk(model, model.work)[0]
    target[0, 3] = math.nan
    with pytest.raises(UnreachableError, match="NaN"):
        ik(model, target)
