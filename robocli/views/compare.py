"""``robocli validate``'s comparison of a measured run with its simulation
(:func:`robocli.io.compare.compare_files`) as text: the per-joint errors as table rows
(:func:`joint_rows`) and what they mean, a line each (:func:`notes`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

__all__ = ["COLUMNS", "joint_rows", "mm_text", "notes", "rad_text", "title"]

#: The columns of :func:`joint_rows`.
COLUMNS = ("joint", "RMSE (rad)", "MAE (rad)", "max |err| (rad)")


def rad_text(value: float) -> str:
    """An error in rad: fixed point from 1e-4 up, else scientific (1e-7 must not read as 0)."""
    return f"{value:.6f}" if value >= 1e-4 or value == 0 else f"{value:.2e}"


def mm_text(value: float | None) -> str:
    """An error in mm, readable at the micrometre level and below."""
    if value is None:
        return "-"
    return f"{value:.3f}" if value >= 0.01 or value == 0 else f"{value:.2e}"


def title(result: Any) -> str:
    return f"sim vs real: {result.samples} samples, time shift {result.delay_s * 1e3:.1f} ms"


def joint_rows(result: Any) -> list[list[str]]:
    """One row per joint: its number, RMSE, MAE and largest error (rad)."""
    return [[str(j + 1), *(rad_text(v[j]) for v in (result.rmse, result.mae, result.max_abs))]
            for j in range(result.rmse.shape[0])]  # fmt: skip


def notes(result: Any, plot: Path | None = None) -> list[str]:
    """What the time shift is, the TCP position error (when known), where the plot went."""
    shift = result.delay_s * 1e3
    # not "delay": against the exact simulator it is mostly the upload's time, not a lag
    out = [f"time shift: the measured motion starts {abs(shift):.1f} ms "
           f"{'later' if shift >= 0 else 'earlier'} in its log than in the simulated one (the "
           "recording ran before the arm moved, e.g. during the upload, plus any controller "
           "lag); the errors are after this alignment"]  # fmt: skip
    if result.tcp_rmse_mm is not None:
        out.append(f"TCP position error: RMSE {mm_text(result.tcp_rmse_mm)} mm, mean "
                   f"{mm_text(result.tcp_mean_mm)} mm, max {mm_text(result.tcp_max_mm)} mm")
    return out + ([f"plot written to {plot}"] if plot is not None else [])
