"""What ``robocli traj`` and ``robocli validate`` do with files, for a script too: write a
trajectory (and its plot) and say what it asks of the robot; compare a measured log with
its simulation, read from any format robocli writes."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from robocli.kinematics.model import RobotModel
    from robocli.kinematics.trajlog import TrajectoryLog

__all__ = ["write_trajectory"]


def write_trajectory(model: RobotModel, log: TrajectoryLog, shape: str, out: str | Path,
                     plot: str | Path | None = None,
                     overwrite: bool = False) -> dict[str, Any]:  # fmt: skip
    """Write ``log`` to ``out`` (.json/.csv/.npz) and, with ``plot``, a PNG of it (the
    ``plot`` extra); return its summary: robot, shape, points, ``duration_s``, the files,
    and the joint that comes nearest its speed limit (``max_speed_joint``, from 1) with
    that fraction of it (``max_speed_fraction``)."""
    import numpy as np

    from robocli.kinematics.trajlog import write_log

    if plot is not None:
        from robocli.kinematics.plot import plot_trajectory

        plot_trajectory(log, Path(plot), title=f"{model.name} {shape}", overwrite=overwrite)
    write_log(log, Path(out), overwrite)
    speeds = np.max(np.abs(log.velocities), axis=0)
    fastest = int(np.argmax(speeds / model.max_speed))
    return {
        "robot": model.name,
        "shape": shape,
        "points": len(log),
        "duration_s": float(log.time[-1] - log.time[0]),
        "out": str(out),
        "plot": None if plot is None else str(plot),
        "max_speed_fraction": float(speeds[fastest] / model.max_speed[fastest]),
        "max_speed_joint": fastest + 1,
    }
