"""``robocli traj`` and ``robocli validate`` as a user runs them: real processes, files,
exit codes and one-line errors (never a traceback)."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from robocli.kinematics.trajlog import TrajectoryLog, read_log, write_log
from robocli.kinematics.validate import shifted
from tests.commands import helpers
from tests.commands.helpers import one_line_error


def run(
    cwd: Path, *args: str, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess[str]:
    """``robocli ARGS`` in ``cwd``, with ``env`` added to the environment."""
    return helpers.run(*args, cwd=cwd, env={**os.environ, **env} if env else None)


def test_traj_circle_writes_the_log_then_validate_against_itself(tmp_path: Path) -> None:
    proc = run(tmp_path, "traj", "circle", "--count", "100")
    assert proc.returncode == 0, proc.stderr
    assert "irb120 circle: 100 points" in proc.stdout
    log = read_log(tmp_path / "sim.json")
    assert len(log) == 100 and log.tcp is not None
    proc = run(tmp_path, "validate", "sim.json", "sim.json", "--json")
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    assert doc["max_rmse_rad"] == 0.0 and doc["samples"] == 100
    assert [j["joint"] for j in doc["joints"]] == [1, 2, 3, 4, 5, 6]


def test_validate_table_reports_a_known_delay(tmp_path: Path) -> None:
    assert run(tmp_path, "traj", "rectangle", "--output", "sim.npz").returncode == 0
    sim = read_log(tmp_path / "sim.npz")
    write_log(shifted(sim, 0.75, pad_s=1.0, noise_rad=0.001), tmp_path / "real.csv")
    proc = run(tmp_path, "validate", "sim.npz", "real.csv")
    assert proc.returncode == 0, proc.stderr
    assert "RMSE (rad)" in proc.stdout
    found = re.search(r"time shift (-?[\d.]+) ms", proc.stdout)
    assert found and abs(float(found.group(1)) - 750.0) < 1e3 * np.median(np.diff(sim.time))
    assert "TCP position error" in proc.stdout


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("traj", "circle", "--robot", "kr1000"), "unknown robot model 'kr1000'; known models: "),
        (("traj", "ptp-joint", "--to", "0,0,80,0,0,0"), "joint 3 at point"),
        (("traj", "ptp-cartesian", "--to", "2,0,0.5"), "is unreachable: outside the workspace"),
        (("traj", "circle", "--duration", "0.05"), "deg/s limit"),
        (("traj", "ptp-joint", "--to", "1,2"), "--to takes 6 numbers, got 2"),
        (("traj", "circle", "--center", "0.3,nan,0.4"), "--center must be finite numbers"),
        (("traj", "file", "missing.json"), "missing.json: cannot read"),
        (("validate", "bad.json", "bad.json"), "bad.json: 'joints_positions' row 1 has 5 values"),
        (("validate", "nan.json", "nan.json"), "nan.json: holds NaN"),
        (("validate", "sim.txt", "sim.txt"), "unknown log suffix '.txt'"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(
    tmp_path: Path, args: tuple[str, ...], message: str
) -> None:
    (tmp_path / "bad.json").write_text(
        '{"time": [0, 1], "joints_positions": [[0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0]]}'
    )
    (tmp_path / "nan.json").write_text(
        '{"time": [0, NaN], "joints_positions": [[0, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0]]}'
    )
    (tmp_path / "sim.txt").write_text("")
    line = one_line_error(run(tmp_path, *args), 2)
    assert message in line
    assert not (tmp_path / "sim.json").exists()  # nothing written on bad input


def test_traj_file_from_csv_waypoints(tmp_path: Path) -> None:
    (tmp_path / "w.csv").write_text(
        "q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg\n0,10,10,0,70,0\n20,15,5,0,60,10\n"
    )
    proc = run(tmp_path, "traj", "file", "w.csv", "--duration", "2", "--output", "w.json")
    assert proc.returncode == 0, proc.stderr
    log = read_log(tmp_path / "w.json")
    np.testing.assert_allclose(np.degrees(log.positions[-1]), [20, 15, 5, 0, 60, 10])
    assert log.time[-1] == pytest.approx(2.0)


def test_plots_are_png_files(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    proc = run(tmp_path, "traj", "circle", "--plot", "traj.png")
    assert proc.returncode == 0, proc.stderr
    proc = run(tmp_path, "validate", "sim.json", "sim.json", "--plot", "cmp.png")
    assert proc.returncode == 0, proc.stderr
    for name in ("traj.png", "cmp.png"):
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_without_matplotlib_the_plot_option_says_how_to_get_it(tmp_path: Path) -> None:
    # a directory named like the package that cannot be imported hides an installed one
    blocker = tmp_path / "block"
    (blocker / "matplotlib").mkdir(parents=True)
    (blocker / "matplotlib" / "__init__.py").write_text("raise ImportError('hidden')\n")
    proc = subprocess.run(
        [
            sys.executable,
            "-c",
            f"import sys; sys.path.insert(0, {str(blocker)!r}); from robocli.cli import main; "
            "sys.exit(main(['traj', 'circle', '--plot', 'x.png']))",
        ],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=tmp_path,
    )
    line = one_line_error(proc, 1)
    assert "pip install robocli-robots[plot]" in line
    assert not (tmp_path / "x.png").exists()


def test_waypoints_csv_with_a_byte_order_mark(tmp_path: Path) -> None:
    """Excel writes UTF-8 CSV with a byte-order mark."""
    rows = ["q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg", "0,10,10,0,70,0", "20,10,10,0,70,0"]
    (tmp_path / "wp.csv").write_bytes(b"\xef\xbb\xbf" + "\r\n".join(rows).encode() + b"\r\n")
    proc = run(tmp_path, "traj", "file", "wp.csv", "--duration", "3", "--output", "f.json")
    assert proc.returncode == 0, proc.stderr
    assert len(read_log(tmp_path / "f.json")) >= 2


def test_validate_a_one_sample_log(tmp_path: Path) -> None:
    assert run(tmp_path, "traj", "circle", "--output", "sim.json").returncode == 0
    sim = read_log(tmp_path / "sim.json")
    write_log(TrajectoryLog.from_positions(sim.time[:1], sim.positions[:1]), tmp_path / "one.json")
    proc = run(tmp_path, "validate", "sim.json", "one.json")
    assert proc.returncode == 2
    assert "the measured log has 1 sample; each log needs at least two" in proc.stderr


def test_validate_table_title_fits_80_columns(tmp_path: Path) -> None:
    assert run(tmp_path, "traj", "circle", "--output", "sim.json").returncode == 0
    sim = read_log(tmp_path / "sim.json")
    write_log(shifted(sim, 13624.0681, pad_s=1.0), tmp_path / "real.json")
    proc = run(tmp_path, "validate", "sim.json", "real.json", env={"COLUMNS": "80"})
    assert proc.returncode == 0, proc.stderr
    title = proc.stdout.splitlines()[0]
    assert "time shift 13624068.1 ms" in title and title.strip().endswith("ms")
