"""The URDFs robocli generates, read by a URDF library of the field (yourdfpy): they parse,
and they are robocli's own models: an arm's flange is robocli's forward kinematics over
1000 random configurations, a Pioneer's wheels, sonar ring and laser are its parameters."""

from __future__ import annotations

import io
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from robocli.kinematics import fk, known_models, load_model
from robocli.robots.pioneer import ROBOT_PARAMS
from robocli.robots.urdf import arm_transforms, joint_origins, rpy, urdf

yourdfpy = pytest.importorskip("yourdfpy")


def load(text: str) -> Any:
    return yourdfpy.URDF.load(io.StringIO(text), build_scene_graph=True, load_meshes=False)


@pytest.mark.parametrize("name", known_models())
def test_an_arms_flange_is_robocli_fk_over_1000_configurations(name: str) -> None:
    model = load_model(name)
    robot = load(urdf(name))
    assert robot.actuated_joint_names == [f"joint_{i + 1}" for i in range(model.n_joints)]
    lo, hi = model.limits[:, 0], model.limits[:, 1]
    assert [j.limit.lower for j in robot.actuated_joints] == pytest.approx(lo, abs=0)
    assert [j.limit.upper for j in robot.actuated_joints] == pytest.approx(hi, abs=0)
    q = np.random.default_rng(120).uniform(lo, hi, size=(1000, model.n_joints))
    want = fk(model, q)
    worst = 0.0
    for qi, wi in zip(q, want, strict=True):
        robot.update_cfg(qi)
        got = robot.get_transform("flange", "base")
        worst = max(worst, float(np.abs(got[:3, 3] - wi[:3, 3]).max()))
        assert got[:3, :3] == pytest.approx(wi[:3, :3], abs=1e-9)
    assert worst < 1e-9


def test_each_links_transform_is_what_a_recording_sends() -> None:
    """:func:`arm_transforms` (the arm's tf in recordings and live views) is the URDF's
    joint transforms, link by link."""
    model = load_model("irb120")
    robot = load(urdf("irb120"))
    q = np.radians([30, -20, 40, 10, -50, 90])
    robot.update_cfg(q)
    names = ["base", *(f"link_{i}" for i in range(1, 7))]
    for i, t in enumerate(arm_transforms(model, q)):
        assert robot.get_transform(names[i + 1], names[i]) == pytest.approx(t, abs=1e-12)
    chain = np.eye(4)
    for t in [*arm_transforms(model, q), joint_origins(model)[-1]]:
        chain = chain @ t
    assert chain == pytest.approx(fk(model, q)[0], abs=1e-12)


def rpy_matrix(r: float, p: float, y: float) -> Any:
    """URDF's fixed-axis roll, pitch, yaw: Rz(y) Ry(p) Rx(r)."""
    cr, sr, cp, sp, cy, sy = (math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y),
                              math.sin(y))  # fmt: skip
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def test_rpy_at_and_near_gimbal_lock() -> None:
    rng = np.random.default_rng(5)
    for pitch in (math.pi / 2, -math.pi / 2, 0.3, math.pi / 2 - 1e-7, -math.pi / 2 + 1e-13):
        for _ in range(20):
            r, y = rng.uniform(-math.pi, math.pi, 2)
            m = rpy_matrix(r, pitch, y)
            assert rpy_matrix(*rpy(m)) == pytest.approx(m, abs=1e-12)


@pytest.mark.parametrize("subtype", sorted(ROBOT_PARAMS))
def test_a_pioneer_is_its_parameters(subtype: str) -> None:
    params = ROBOT_PARAMS[subtype]
    robot = load(urdf(subtype, prefix="pioneer/"))
    assert robot.base_link == "pioneer/base_link"
    for side, y in (("left", params.half_track), ("right", -params.half_track)):
        t = robot.get_transform(f"pioneer/{side}_wheel", "pioneer/base_link")
        assert t[:3, 3] == pytest.approx([0.0, y, params.wheel_radius], abs=1e-12)
        assert robot.joint_map[f"{side}_wheel_joint"].type == "continuous"
    for i, s in enumerate(params.sonar):
        if (s.x, s.y) == (0.0, 0.0):
            continue
        t = robot.get_transform(f"pioneer/sonar_{i}", "pioneer/base_link")
        assert t[:2, 3] == pytest.approx([s.x, s.y], abs=1e-12)
        assert t[:2, 0] == pytest.approx([math.cos(s.th), math.sin(s.th)], abs=1e-12)
    m = params.laser_mount
    t = robot.get_transform("pioneer/laser", "pioneer/base_link")
    assert t[:2, 3] == pytest.approx([m.x, m.y], abs=1e-12)


def test_the_command_writes_a_file_and_keeps_one_that_exists(tmp_path: Path) -> None:
    out = tmp_path / "p3dx.urdf"
    run = [sys.executable, "-m", "robocli", "urdf", "p3dx", "-o", str(out)]
    proc = subprocess.run(run, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert out.read_text() == urdf("p3dx")
    out.write_text("mine")
    proc = subprocess.run(run, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "exists" in proc.stderr and out.read_text() == "mine"
    proc = subprocess.run([sys.executable, "-m", "robocli", "urdf", "nao"], capture_output=True,
                          text=True, timeout=120)  # fmt: skip
    assert proc.returncode == 2 and "irb120" in proc.stderr and "Traceback" not in proc.stderr
