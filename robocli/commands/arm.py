"""``robocli sim abb``, ``upload arm``, ``monitor arm``, ``connect arm``: thin layers over
:class:`robocli.devices.arm.Arm` and :class:`robocli.sim.abb.server.AbbSim`.

``HOST`` may be ``sim``: an embedded simulator in exact mode, reporting the controller time
(JOINT_FEEDBACK) every 5 ms, so that a monitored run validates to the float; with
``--stream`` (``upload``, ``teleop``) it is the streaming profile (``sim abb --profile
generic``), as an ABB never executes streamed points.
"""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer

from robocli.commands import _arm
from robocli.commands import _common as common
from robocli.commands import _options as opt
from robocli.commands._live import FoxgloveHostOpt, FoxgloveOpt
from robocli.commands._replay import LoopOpt, ReplayOpt, SpeedOpt, abb_replay, check_replay
from robocli.commands.kinematics import _floats

if TYPE_CHECKING:
    from robocli.devices.arm import Arm
    from robocli.devices.arm.state import JointRecorder

# ------------------------------------------------------------------------------ sim abb


def _model_option(name: str, help: str, max: float = 10_000.0) -> Any:
    """An option of ``sim abb``'s controller model: 0 (exact) by default."""
    return typer.Option(0.0, name, min=0.0, max=max, help=help)


def _port_option(default: int, name: str, server: str) -> Any:
    return typer.Option(default, name, min=0, max=65535, help=f"{server} TCP port (0: any).")


def simulate(
    motion_port: int = _port_option(11000, "--motion-port", "Motion server's"),
    state_port: int = _port_option(11002, "--state-port", "State server's"),
    state_ms: float | None = typer.Option(None, "--state-ms", min=0.5, max=10_000.0, help="State "
                                          "period, ms (default: 100 as ABB's stock code; 20 with "
                                          "--paper)."),  # fmt: skip
    byte_order: _arm.ByteOrder = _arm.OrderOpt,
    real_size: _arm.RealSize = _arm.RealOpt,
    profile: _arm.Profile = typer.Option("abb", "--profile", help="abb (RAPID servers) or generic "
                                         "(streaming server)."),  # fmt: skip
    robot: str = opt.RobotOpt,
    latency_ms: float = _model_option("--latency-ms", "Motion reply delay, ms."),
    jitter_ms: float = _model_option("--jitter-ms", "Motion reply jitter: std of a skewed extra "
                                     "delay, ms."),  # fmt: skip
    noise_rad: float = _model_option("--noise-rad", "Gaussian noise on reported joints, rad.", 1.0),
    period_jitter_ms: float = _model_option("--period-jitter-ms", "State period std, ms (each "
                                            "period drawn afresh, skewed as the paper's)."),
    lag_ms: float = _model_option("--lag-ms", "Execution delay after activation, ms."),
    paper: bool = opt.flag("--paper", "The paper-like controller model."),
    feedback: bool = opt.flag("--feedback", "Also send JOINT_FEEDBACK with the controller time."),
    time_scale: float = opt.TimeScaleOpt,
    bind: str = opt.BindOpt,
    replay: Path | None = ReplayOpt,
    speed: float | None = SpeedOpt,
    loop: bool = LoopOpt,
) -> None:
    """Run a simulated ABB controller (RAPID motion and state servers) until Ctrl-C."""
    from robocli.sim.launch import abb_controller

    rate = check_replay(replay, speed, loop)
    if motion_port == state_port != 0:
        raise typer.BadParameter(
            f"--motion-port and --state-port are both {motion_port}: the motion and the state "
            "server each need their own port"
        )
    if replay is not None:
        abb_replay(replay, rate, loop, robot, profile, bind, motion_port, state_port)
        return
    options = {"latency_ms": latency_ms, "jitter_ms": jitter_ms, "noise_rad": noise_rad,
               "period_jitter_ms": period_jitter_ms, "lag_ms": lag_ms}  # fmt: skip
    with common.sigterm_as_interrupt(), abb_controller(
        robot, profile=profile, state_ms=state_ms, byte_order=byte_order, real_size=real_size,
        time_scale=time_scale, paper=paper, feedback=feedback, **options) as simulator:  # fmt: skip
        with common.listening(bind):
            motion, state = simulator.serve_tcp(common.bind_address(bind), motion_port, state_port)
        typer.echo(
            f"{simulator.robot.name} ({profile}): motion {motion}, state {state}, state every "
            f"{simulator.state_ms:g} ms" + ("" if simulator.ctl_model.exact else ", model on")
        )
        common.wait_forever()  # Ctrl-C, SIGTERM: the simulator closes, exit 130


# ------------------------------------------------------------------------------ upload arm

WAIT_HELP = "Seconds to wait for the end (0: do not wait; the arm moves on)."


class _Progress:
    """A Rich bar on a terminal, plain lines otherwise."""

    def __init__(self) -> None:
        self.tty = sys.stdout.isatty()
        self._bar: Any = None
        self._task: Any = None
        self._last = 0

    def __enter__(self) -> _Progress:
        if self.tty:
            from rich.progress import Progress

            self._bar = Progress()
            self._bar.start()
            self._task = self._bar.add_task("points acknowledged", total=None)
        return self

    def __call__(self, done: int, total: int) -> None:
        if self._bar is not None:
            self._bar.update(self._task, completed=done, total=total)
        elif done == total or done - self._last >= 10:
            self._last = done
            typer.echo(f"acknowledged {done}/{total}")

    def __exit__(self, *exc: object) -> None:
        if self._bar is not None:
            self._bar.stop()


@_arm.arm_link()
def upload(
    host: str = _arm.HostArg,
    shape: _arm.Shape | None = typer.Option(None, "--shape", help="circle or rectangle."),
    points: int = opt.count_option(100, "Points of the --shape.", min=1, max=100_000),
    file: Path | None = typer.Option(None, "--file", help="Trajectory log (.json/.csv/.npz)."),
    duration: float | None = opt.duration_option(None, "Shape duration, s."),
    radius: float = typer.Option(0.05, "--radius", min=1e-4, max=5.0, help="Shape size, m."),
    center: str | None = typer.Option(None, "--center", help="Shape centre x,y,z, m."),
    monitor: Path | None = opt.output_option(None, "Log the run's states to this file "
                                             "(.json/.csv/.npz)."),  # fmt: skip
    record_to: Path | None = typer.Option(None, "--record", metavar="FILE.mcap", dir_okay=False,
                                          help="Record this upload's connection (both ports, "
                                          "every frame) to an MCAP file."),  # fmt: skip
    ros2: bool = opt.flag("--ros2", "--record a ROS 2 bag (docs/ros2-bags.md)."),
    overwrite: bool = opt.OverwriteOpt,
    split: bool = opt.flag("--split", "Upload > 100 points in several parts."),
    stream: bool = opt.StreamOpt,
    link: _arm.ArmLink = _arm.LINK,
    wait: float = typer.Option(600.0, "--wait", min=0.0, max=86_400.0, help=WAIT_HELP),
) -> None:
    """Upload a trajectory (download -1..-3, each point acknowledged) and wait for its end."""
    from robocli.devices.arm.jobs import run_trajectory, shape_trajectory
    from robocli.kinematics.trajlog import check_writable, read_log

    if monitor is not None and wait == 0:
        raise typer.BadParameter("--output logs until the end: give --wait > 0")
    if monitor is not None:
        check_writable(monitor, overwrite)  # before the arm moves: not after the whole run
    if (shape is None) == (file is None):
        raise typer.BadParameter("give --shape or --file")
    c = _floats(center, 3, "--center")
    traj = read_log(file) if file is not None else \
        shape_trajectory(link.robot, str(shape), points, radius, c, duration)  # fmt: skip
    with _recorded(record_to, link, overwrite, ros2) as (rec, listeners), \
            _arm.connected(host, link, stream, listeners=listeners) as arm:  # fmt: skip
        if rec is not None:
            rec.add(arm, "arm")
            rec.begin()  # connected: now the file is made
            typer.echo(f"recording to {rec.path}", err=True)
        kept = recording(arm, monitor, overwrite=overwrite) if monitor is not None else None
        sent = run_trajectory(arm, traj, split=split, stream=stream, wait=wait,
                              progress=_Progress, kept=kept, say=typer.echo)  # fmt: skip
    typer.echo(f"uploaded {sent} points; " +
               ("the arm is moving, not waiting" if wait == 0 else "arm idle"))  # fmt: skip


@contextlib.contextmanager
def _recorded(path: Path | None, link: _arm.ArmLink, overwrite: bool,
              ros2: bool = False) -> Iterator[tuple[Any, dict[str, Any]]]:  # fmt: skip
    """``upload --record``: a recorder (not begun: the file is made once connected) and the
    listeners to connect the arm with (:func:`robocli.io.record.upload.upload_recorder`); the
    recording is closed after the arm (its stop is recorded) and says what it holds,
    however the upload ends. ``(None, {})`` without a path."""
    if path is None:
        yield None, {}
        return
    from robocli.commands.record import close_recording
    from robocli.io.record.upload import upload_recorder

    if path.suffix != ".mcap":
        raise typer.BadParameter(f"--record {path}: a recording needs a .mcap name")
    rec, listeners = upload_recorder(path, byte_order=link.byte_order, real_size=link.real_size,
                                     overwrite=overwrite, ros2=ros2)  # fmt: skip
    start = time.monotonic()
    try:
        yield rec, listeners
    finally:
        with common.shielded():
            close_recording(rec, time.monotonic() - start)


# ------------------------------------------------------------------------------ monitor, connect


@contextlib.contextmanager
def recording(arm: Arm, out: Path, max_samples: int | None = None, *,
              overwrite: bool = False) -> Iterator[JointRecorder]:  # fmt: skip
    """:class:`~robocli.devices.arm.jobs.KeptLog` saying on stderr how many samples went
    where, or why none did."""
    from robocli.devices.arm.jobs import KeptLog

    kept = KeptLog(arm, out, max_samples, overwrite=overwrite)
    try:
        with kept as rec:
            yield rec
    finally:
        if kept.error is not None:
            typer.echo(f"{out} not written: {kept.error}", err=True)
        if kept.written is not None:
            log = kept.written
            typer.echo(f"recorded {len(log)} samples over {log.time[-1] - log.time[0]:.3f} s "
                       f"-> {out}", err=True)  # fmt: skip


@_arm.arm_link(motion=False)
def monitor(
    host: str = _arm.HostArg,
    out: Path = opt.output_option(Path("real.json"), "Log to write (.json/.csv/.npz)."),
    overwrite: bool = opt.OverwriteOpt,
    samples: int | None = opt.count_option(None, "States to record (default: until Ctrl-C).", min=2,
                                           max=1_000_000),  # fmt: skip
    duration: float | None = opt.duration_option(None, "Seconds to record (a few states).", min=0.5,
                                                 max=86_400.0),  # fmt: skip
    link: _arm.ArmLink = _arm.LINK,
) -> None:
    """Record the state stream (independently of any upload) to a JSON/CSV/NPZ log, for
    --count, --duration or until Ctrl-C; the log is written however it ends."""
    from robocli.devices.arm.jobs import record_states
    from robocli.kinematics.trajlog import check_writable

    if samples is not None and duration is not None:
        raise typer.BadParameter("give --count or --duration, not both")
    check_writable(out, overwrite)  # before recording: not after the whole --duration
    with _arm.connected(host, link) as arm, \
            recording(arm, out, samples and 2 * samples, overwrite=overwrite) as rec:  # fmt: skip
        if samples is None and duration is None:
            typer.echo(f"recording to {out} until Ctrl-C", err=True)
        record_states(arm, rec, samples, duration, link.timeout)


@_arm.arm_link(motion=False)
def connect(
    host: str = _arm.HostArg,
    once: bool = opt.flag("--once", "Print one state and exit."),
    json_out: bool = opt.json_option(),
    count: int | None = opt.count_option(None, "Stop after N states.", min=1),
    foxglove: int | None = FoxgloveOpt,
    foxglove_host: str = FoxgloveHostOpt,
    link: _arm.ArmLink = _arm.LINK,
) -> None:
    """Show the arm's live joints (deg), TCP position and status until q (on a terminal)
    or Ctrl-C (--json: every field, rad too; --foxglove: also to Foxglove, with every
    link's frame)."""
    from robocli.commands._live import live_view
    from robocli.views.arm import state_text, states
    from robocli.views.keys import QUIT_KEYS, keyboard

    with common.reader_may_leave(), live_view(foxglove, foxglove_host) as view, \
            _arm.connected(host, link) as arm, keyboard() as read_key:  # fmt: skip
        if view is not None:
            view.add(arm)
        shown, last = 0, 0.0
        for d in states(arm, link.timeout):  # Ctrl-C: exit 130 (the link closed on the way out)
            if once:
                common.print_json(common.rounded(d)) if json_out else typer.echo(state_text(d))
                return
            if json_out:
                common.print_json(common.rounded(d))
                shown += 1
            elif d["t"] - last >= 0.1:
                typer.echo(state_text(d))
                shown, last = shown + 1, d["t"]
            if count is not None and shown >= count:
                return
            if read_key is not None and read_key(0) in QUIT_KEYS:
                return  # as the Pioneer's view
