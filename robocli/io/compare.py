"""Comparing a simulated and a measured arm log read from any file robocli writes (the
trajectory log formats and MCAP recordings): :func:`compare_files`."""

from __future__ import annotations

from pathlib import Path

from robocli.kinematics.validate import Validation

__all__ = ["compare_files"]


def compare_files(sim: str | Path, real: str | Path, robot: str | None = "irb120",
                  plot: str | Path | None = None,
                  overwrite: bool = False) -> Validation:  # fmt: skip
    """Read a simulated and a measured log (.json/.csv/.npz/.mcap), align them in time and
    compare them (:func:`robocli.kinematics.validate.validate`), the TCP error with model
    ``robot`` when it has the logs' joints; with ``plot``, a PNG of the comparison."""
    from robocli.io.export import read_any_log
    from robocli.kinematics import load_model
    from robocli.kinematics.validate import validate

    sim_log, real_log = read_any_log(Path(sim)), read_any_log(Path(real))
    model = load_model(robot) if robot else None
    if model is not None and model.n_joints != sim_log.n_joints:
        model = None
    result = validate(sim_log, real_log, model)
    if plot is not None:
        from robocli.kinematics.plot import plot_validation

        plot_validation(sim_log, real_log, result, Path(plot), model, overwrite)
    return result
