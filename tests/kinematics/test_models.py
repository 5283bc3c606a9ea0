"""Robot models: shipped files, published reference poses, IRB120 home and limit poses."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from robocli.errors import EXIT_USAGE, RobocliError
from robocli.kinematics import (
    ModelFileError,
    UnknownModelError,
    fk,
    fk_positions,
    known_models,
    load_model,
)

MODELS_DIR = Path(__file__).resolve().parents[2] / "robocli" / "kinematics" / "models"


def test_shipped_models_include_the_three_robots() -> None:
    assert {"irb120", "ur3e", "lrmate200id"} <= set(known_models())


@pytest.mark.parametrize("name", ["irb120", "ur3e", "lrmate200id"])
def test_each_model_meets_its_published_reference_pose(name: str) -> None:
    model = load_model(name)
    assert model.reference_poses, f"{name} ships no reference pose"
    for ref in model.reference_poses:
        np.testing.assert_allclose(fk_positions(model, ref.joints)[0], ref.tcp, rtol=0, atol=1e-9)


def test_irb120_home_is_the_calibration_pose_exactly() -> None:
    model = load_model("irb120")
    pose = fk(model, model.home)[0]
    np.testing.assert_allclose(pose[:3, 3], [0.374, 0.0, 0.630], rtol=0, atol=1e-9)
    # flange faces forward (+x), as on the calibration position
    np.testing.assert_allclose(pose[:3, 2], [1.0, 0.0, 0.0], atol=1e-12)


def _irb120_by_geometry(q1: float, q2: float, q3: float, q5: float) -> np.ndarray:
    """IRB120 flange from its drawing dimensions, independent of DH: shoulder 290 mm up,
    upper arm 270 mm, elbow offset 70 mm, forearm 302 mm, flange 72 mm; q4 = q6 = 0."""
    r_el, z_el = 0.270 * math.sin(q2), 0.290 + 0.270 * math.cos(q2)
    phi = q2 + q3  # forearm pitch below horizontal
    r_wc = r_el + 0.302 * math.cos(phi) + 0.070 * math.sin(phi)
    z_wc = z_el - 0.302 * math.sin(phi) + 0.070 * math.cos(phi)
    r = r_wc + 0.072 * math.cos(phi + q5)
    z = z_wc - 0.072 * math.sin(phi + q5)
    return np.array([r * math.cos(q1), r * math.sin(q1), z])


def test_irb120_limit_poses_match_the_drawing_geometry() -> None:
    model = load_model("irb120")
    lim = model.limits
    poses = []
    for q1 in (lim[0, 0], 0.0, lim[0, 1]):
        for q2 in (lim[1, 0], 0.0, lim[1, 1]):
            for q3 in (lim[2, 0], 0.0, lim[2, 1]):
                for q5 in (lim[4, 0], lim[4, 1]):
                    poses.append((q1, q2, q3, q5))
    q = np.array([[a, b, c, 0.0, e, 0.0] for a, b, c, e in poses])
    got = fk_positions(model, q)
    want = np.array([_irb120_by_geometry(*p) for p in poses])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def test_unknown_model_is_a_usage_error_listing_the_known_ones() -> None:
    with pytest.raises(UnknownModelError) as info:
        load_model("irb9999")
    assert info.value.exit_code == EXIT_USAGE
    assert isinstance(info.value, RobocliError)
    for name in known_models():
        assert name in str(info.value)


def test_a_new_robot_is_a_new_file(tmp_path: Path) -> None:
    doc = json.loads((MODELS_DIR / "irb120.json").read_text())
    doc["name"] = "irb120-long"
    doc["dh"]["d"][3] = 0.402  # a longer forearm
    path = tmp_path / "long.json"
    path.write_text(json.dumps(doc))
    model = load_model(path)
    np.testing.assert_allclose(fk_positions(model, model.home)[0], [0.474, 0, 0.630], atol=1e-12)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d.pop("dh"), "missing key 'dh'"),
        (lambda d: d["dh"].update(d=[0.1, 0.2]), "'d' has 2 values, expected 6"),
        (lambda d: d.update(limits_deg=[[10, -10]] * 6), "lower < upper"),
        (lambda d: d.update(max_speed_deg_s=[0] * 6), "positive"),
        (lambda d: d["dh"].update(a=["x"] * 6), "must hold numbers"),
    ],
)
def test_malformed_model_files_fail_with_one_clear_line(tmp_path: Path, edit, message) -> None:
    doc = json.loads((MODELS_DIR / "irb120.json").read_text())
    edit(doc)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(ModelFileError, match=message) as info:
        load_model(path)
    assert "\n" not in str(info.value)


def test_model_file_nested_too_deeply_or_endless(tmp_path: Path) -> None:
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 50_000)  # under the size cap, past the JSON parser's depth
    with pytest.raises(ModelFileError, match="nested too deeply"):
        load_model(deep)
    endless = tmp_path / "zero.json"
    endless.symlink_to("/dev/zero")  # stat says 0 bytes
    with pytest.raises(ModelFileError, match="at most"):
        load_model(endless)


def test_model_file_with_nan_is_refused(tmp_path: Path) -> None:
    text = (MODELS_DIR / "irb120.json").read_text().replace('"a": [0.0,', '"a": [NaN,')
    path = tmp_path / "nan.json"
    path.write_text(text)
    with pytest.raises(ModelFileError, match="NaN"):
        load_model(path)
