"""PNG plots of trajectories and of simulated-vs-measured runs (matplotlib, optional extra)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from robocli.errors import RobocliError
from robocli.kinematics.fk import fk_positions
from robocli.kinematics.model import RobotModel
from robocli.kinematics.trajlog import TrajectoryLog
from robocli.kinematics.validate import Validation


class PlotUnavailableError(RobocliError):
    """matplotlib is not installed."""


def _pyplot() -> Any:
    try:
        import matplotlib  # type: ignore[import-not-found,unused-ignore]  # optional extra
    except ImportError:
        raise PlotUnavailableError(
            "plotting needs matplotlib: pip install robocli-robots[plot]"
        ) from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # type: ignore[import-not-found,unused-ignore]

    return plt


def save_png(fig: Any, path: str | Path, overwrite: bool = False) -> Path:
    """Write ``fig`` as a PNG (whole or not at all; see :func:`~robocli.output.
    replace_output`)."""
    from robocli.output import replace_output

    out = Path(path)
    with replace_output(out, overwrite) as fh:
        fig.savefig(fh, dpi=110, format="png")
    return out


def plot_trajectory(log: TrajectoryLog, path: str | Path, title: str = "",
                    overwrite: bool = False) -> Path:  # fmt: skip
    """Joint angles over time and the TCP path (x-y and x-z views) as a PNG."""
    plt = _pyplot()
    fig, axes = plt.subplots(1, 3 if log.tcp is not None else 1, figsize=(14, 4), squeeze=False)
    ax = axes[0][0]
    for j in range(log.n_joints):
        ax.plot(log.time, np.degrees(log.positions[:, j]), label=f"q{j + 1}")
    ax.set(xlabel="time (s)", ylabel="joint (deg)", title=title or "joints")
    ax.legend(fontsize=7)
    if log.tcp is not None:
        for ax, (i, k, name) in zip(axes[0][1:], ((0, 1, "x-y"), (0, 2, "x-z")), strict=False):
            ax.plot(log.tcp[:, i] * 1e3, log.tcp[:, k] * 1e3, ".-", markersize=3)
            ax.set(xlabel=f"{name[0]} (mm)", ylabel=f"{name[2]} (mm)", title=f"TCP {name}")
            ax.set_aspect("equal", adjustable="datalim")
    fig.tight_layout()
    try:
        return save_png(fig, path, overwrite)
    finally:
        plt.close(fig)


def plot_validation(sim: TrajectoryLog, meas: TrajectoryLog, result: Validation,
                    path: str | Path, model: RobotModel | None = None,
                    overwrite: bool = False) -> Path:  # fmt: skip
    """Each joint simulated vs measured (measured shifted onto the simulated clock), and the
    TCP paths, as a PNG. A log without a TCP column gets one from ``model``'s FK."""
    plt = _pyplot()
    sim_tcp, meas_tcp = sim.tcp, meas.tcp
    if model is not None and model.n_joints == sim.n_joints:
        sim_tcp = fk_positions(model, sim.positions) if sim_tcp is None else sim_tcp
        meas_tcp = fk_positions(model, meas.positions) if meas_tcp is None else meas_tcp
    n = sim.n_joints
    cols = 3
    rows = (n + cols - 1) // cols + 1
    fig, axes = plt.subplots(rows, cols, figsize=(13, 3.2 * rows), squeeze=False)
    t_meas = meas.time - result.delay_s
    for j in range(n):
        ax = axes[j // cols][j % cols]
        ax.plot(sim.time, sim.positions[:, j], label="simulated")
        ax.plot(t_meas, meas.positions[:, j], "--", label="measured")
        ax.set(
            title=f"joint {j + 1}: RMSE {result.rmse[j]:.2e} rad", xlabel="time (s)", ylabel="rad"
        )
        ax.legend(fontsize=7)
    last = axes[rows - 1]
    if sim_tcp is not None:
        for ax, (i, k, name) in zip(last, ((0, 1, "x-y"), (0, 2, "x-z")), strict=False):
            ax.plot(sim_tcp[:, i] * 1e3, sim_tcp[:, k] * 1e3, label="simulated")
            if meas_tcp is not None:
                ax.plot(meas_tcp[:, i] * 1e3, meas_tcp[:, k] * 1e3, "--", label="measured")
            ax.set(title=f"TCP {name}", xlabel=f"{name[0]} (mm)", ylabel=f"{name[2]} (mm)")
            ax.set_aspect("equal", adjustable="datalim")
            ax.legend(fontsize=7)
    for j in range(n, (rows - 1) * cols):
        axes[j // cols][j % cols].axis("off")
    last[2].axis("off")
    fig.suptitle(f"delay {result.delay_s * 1e3:.1f} ms, max RMSE {np.max(result.rmse):.2e} rad")
    fig.tight_layout()
    try:
        return save_png(fig, path, overwrite)
    finally:
        plt.close(fig)
