"""``robocli traj ...`` and ``robocli validate``: thin layers over robocli.kinematics.

NumPy and the kinematics package are imported inside the commands, so that
``robocli --help`` stays fast.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import typer

from robocli.commands import _options as opt
from robocli.commands._common import bundled, print_json

if TYPE_CHECKING:
    from robocli.kinematics.model import RobotModel
    from robocli.kinematics.trajlog import TrajectoryLog
else:  # what the builders return, for the signature trajectory_command reads (NumPy stays unloaded)
    TrajectoryLog = Any

PointsOpt = opt.count_option(100, "Number of points.", min=2, max=100_000)
OutOpt = opt.output_option(Path("sim.json"), "Log to write (.json, .csv or .npz).")
PlotOpt = typer.Option(None, "--plot", help="Also write a PNG plot (needs robocli-robots[plot]).")
SpeedOpt = typer.Option(None, "--speed", help="TCP speed, m/s (default 0.05).")
DurationOpt = opt.duration_option(None, "Total duration, s (instead of --speed).")
StartOpt = typer.Option(None, "--start", help="Start pose, comma-separated joint angles in deg "
                        "(default: work pose).")  # fmt: skip
CenterOpt = typer.Option(None, "--center", help="Centre x,y,z in m (default: start pose TCP).")
PlaneOpt = typer.Option("xy", "--plane", help="Plane of the shape: xy, yz or xz.")
JsonOpt = opt.json_option("One line: a JSON summary instead of text.")


def _floats(text: str | None, n: int | None, name: str) -> list[float] | None:
    if text is None:
        return None
    try:
        values = [float(v) for v in text.replace(" ", "").split(",") if v]
    except ValueError:
        raise typer.BadParameter(f"{name} takes comma-separated numbers, not {text!r}") from None
    if n is not None and len(values) != n:
        raise typer.BadParameter(f"{name} takes {n} numbers, got {len(values)}")
    if not all(math.isfinite(v) for v in values):
        raise typer.BadParameter(f"{name} must be finite numbers")
    return values


def _start(model: RobotModel, start: str | None) -> Any:
    values = _floats(start, model.n_joints, "--start")
    return None if values is None else [math.radians(v) for v in values]


@dataclass(frozen=True)
class Timing:
    """What every trajectory shares, as the options gave it: the model, the start pose (rad,
    ``None``: the model's work pose), the number of points, and the TCP speed (m/s) or the
    total duration (s); where its log (and plot) go, and whether as JSON."""

    model: RobotModel
    q_start: list[float] | None
    points: int
    speed: float | None
    duration: float | None
    out: Path
    plot: Path | None
    overwrite: bool
    json_out: bool


def _timing(robot: str, speed: float | None, duration: float | None, start: str | None,
            out: Path, plot: Path | None, overwrite: bool, json_out: bool,
            points: int = 0) -> Timing:  # fmt: skip
    """The options as a :class:`Timing`: the model loaded, the log and the plot refused
    before anything is computed (see :mod:`robocli.output`), the start pose parsed."""
    from robocli.kinematics import load_model
    from robocli.kinematics.trajlog import check_writable
    from robocli.output import check_output

    model = load_model(robot)
    check_writable(out, overwrite)
    if plot is not None:
        check_output(plot, overwrite)
    return Timing(model, _start(model, start), points, speed, duration, out, plot, overwrite,
                  json_out)  # fmt: skip


def _finish(t: Timing, log: TrajectoryLog, shape: str) -> None:
    from robocli.kinematics.files import write_trajectory

    summary = write_trajectory(t.model, log, shape, t.out, t.plot, t.overwrite)
    if t.json_out:
        print_json(summary)
        return
    fastest, fraction = summary["max_speed_joint"], summary["max_speed_fraction"]
    typer.echo(
        f"{t.model.name} {shape}: {len(log)} points over {summary['duration_s']:.3f} s, "
        f"fastest joint {fastest} at {math.degrees(fraction * t.model.max_speed[fastest - 1]):.1f}"
        f" deg/s ({100 * fraction:.0f}% of its limit) -> {t.out}"
        + (f", plot {t.plot}" if t.plot else "")
    )


#: Where a ``traj`` builder takes the options every trajectory shares: ``timing: Timing =
#: TIMING``, its last parameter (see :func:`trajectory_command`).
TIMING: Any = None
#: The options of every ``traj`` command, after the shape's own ones.
_SHARED = [
    ("robot", str, opt.RobotOpt),
    ("points", int, PointsOpt),
    ("speed", float | None, SpeedOpt),
    ("duration", float | None, DurationOpt),
    ("start", str | None, StartOpt),
    ("out", Path, OutOpt),
    ("plot", Path | None, PlotOpt),
    ("overwrite", bool, opt.OverwriteOpt),
    ("json_out", bool, JsonOpt),
]


def trajectory_command(shape: str, points: bool = True) -> Callable[[Any], Callable[..., None]]:
    """Make a ``traj`` command of a shape's builder, which takes the shape's own options and
    last ``timing: Timing = TIMING``, and returns the log. The command has the shape's
    options followed by those every trajectory shares (``--robot``, ``--points`` unless
    ``points`` is false, ``--speed``, ``--duration``, ``--start``, ``--out``, ``--plot``,
    ``--json``: :func:`~robocli.commands._common.bundled` as a :class:`Timing`), then
    writes the log and prints its summary."""
    shared = [p for p in _SHARED if points or p[0] != "points"]

    def decorate(build: Any) -> Callable[..., None]:
        @functools.wraps(build)
        def command(**options: Any) -> None:
            _finish(options["timing"], build(**options), shape)

        return bundled("timing", shared, _timing)(command)

    return decorate


@trajectory_command("circle")
def circle(
    radius: float = typer.Option(0.05, "--radius", min=1e-4, max=5.0, help="Radius, m."),
    center: str | None = CenterOpt,
    plane: Literal["xy", "yz", "xz"] = PlaneOpt,
    timing: Timing = TIMING,
) -> TrajectoryLog:
    """A circle in a plane through IK, sampled ideally and written as a log."""
    from robocli.kinematics.trajectory import circle as make

    t = timing
    return make(t.model, t.points, radius, _floats(center, 3, "--center"), plane, t.q_start,
                t.speed, t.duration)  # fmt: skip


@trajectory_command("rectangle")
def rectangle(
    width: float = typer.Option(0.10, "--width", min=1e-4, max=5.0, help="Width, m."),
    height: float = typer.Option(0.06, "--height", min=1e-4, max=5.0, help="Height, m."),
    center: str | None = CenterOpt,
    plane: Literal["xy", "yz", "xz"] = PlaneOpt,
    timing: Timing = TIMING,
) -> TrajectoryLog:
    """A rectangle in a plane through IK, sampled ideally and written as a log."""
    from robocli.kinematics.trajectory import rectangle as make

    t = timing
    return make(t.model, t.points, width, height, _floats(center, 3, "--center"), plane,
                t.q_start, t.speed, t.duration)  # fmt: skip


@trajectory_command("ptp-joint")
def ptp_joint(
    to: str = typer.Option(..., "--to", help="Goal joint angles, comma-separated, deg."),
    timing: Timing = TIMING,
) -> TrajectoryLog:
    """Joint-space point-to-point move with a quintic profile."""
    from robocli.kinematics.trajectory import ptp_joint as make

    t = timing
    goal = [math.radians(v) for v in _floats(to, t.model.n_joints, "--to") or []]
    return make(t.model, goal, t.points, t.q_start, t.speed, t.duration)


@trajectory_command("ptp-cartesian")
def ptp_cartesian(
    to: str = typer.Option(..., "--to", help="Goal TCP position x,y,z, m."),
    timing: Timing = TIMING,
) -> TrajectoryLog:
    """Straight TCP line to a point, keeping the start orientation, through IK."""
    from robocli.kinematics.trajectory import ptp_cartesian as make

    t = timing
    return make(t.model, _floats(to, 3, "--to") or [], t.points, t.q_start, t.speed, t.duration)


@trajectory_command("file", points=False)
def file(
    waypoints: Path = typer.Argument(..., help="Waypoints: .json or .csv (joints or x,y,z)."),
    timing: Timing = TIMING,
) -> TrajectoryLog:
    """User waypoints from a file; times from the file, else from --speed or --duration."""
    from robocli.io.waypoints import read_waypoints
    from robocli.kinematics.trajectory import waypoints as make

    t = timing
    wp = read_waypoints(waypoints)
    file_times = wp.time if t.speed is None and t.duration is None else None
    return make(t.model, wp.joints, wp.points, file_times, t.q_start, t.speed, t.duration)


def validate(
    sim: Path = typer.Argument(..., help="Simulated log (.json, .csv, .npz, .mcap)."),
    real: Path = typer.Argument(..., help="Measured log (.json, .csv, .npz, .mcap)."),
    robot: str = typer.Option("irb120", "--robot", help="Model for the TCP error when a log has "
                              "no TCP column."),  # fmt: skip
    plot: Path | None = typer.Option(None, "--plot", help="Write a PNG comparison."),
    overwrite: bool = opt.OverwriteOpt,
    json_out: bool = opt.json_option(),
) -> None:
    """Align a measured run with its simulation in time, then per-joint RMSE/MAE and TCP error."""
    from robocli.io.compare import compare_files
    from robocli.output import check_output

    if plot is not None:
        check_output(plot, overwrite)  # before reading the logs
    result = compare_files(sim, real, robot, plot, overwrite)
    if json_out:
        print_json(result.to_dict())
        return
    _table(result, plot)


def _table(result: Any, plot: Path | None) -> None:
    from rich.console import Console
    from rich.table import Table

    from robocli.views.compare import COLUMNS, joint_rows, notes, title

    table = Table(title=title(result))
    for name in COLUMNS:
        table.add_column(name, justify="right")
    for row in joint_rows(result):
        table.add_row(*row)
    console = Console()
    console.print(table)
    for line in notes(result, plot):
        console.print(line)
