"""``robocli sim abb``, ``upload arm``, ``monitor arm``, ``connect arm``: thin layers over
:class:`robocli.devices.arm.Arm` and :class:`robocli.sim.abb.server.AbbSim`.

``HOST`` may be ``sim``: an embedded simulator in exact mode, reporting the controller time
(JOINT_FEEDBACK) every 5 ms, so that a monitored run validates to the float; with
``--stream`` (``upload``, ``teleop``) it is the streaming profile (``sim abb --profile
generic``), as an ABB never executes streamed points.
"""

from __future__ import annotations

import contextlib
import math
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer

from robocli.commands._arm import (
    LINK,
    ArmLink,
    ByteOrder,
    HostArg,
    OrderOpt,
    Profile,
    RealOpt,
    RealSize,
    RobotOpt,
    Shape,
    arm_link,
    check_wire,
    connected,
)
from robocli.commands._common import (
    OverwriteOpt,
    bind_address,
    listening,
    print_json,
    print_json_line,
    reader_may_leave,
    rounded,
    shielded,
    sigterm_as_interrupt,
    unix_stamped,
)
from robocli.commands._live import FoxgloveHostOpt, FoxgloveOpt
from robocli.commands._options import count_option, duration_option, json_option, output_option
from robocli.commands._replay import LoopOpt, ReplayOpt, SpeedOpt, abb_replay, check_replay

if TYPE_CHECKING:
    from robocli.devices.arm import Arm
    from robocli.devices.arm.state import JointRecorder
    from robocli.kinematics.trajlog import TrajectoryLog

# ------------------------------------------------------------------------------ sim abb


def simulate(
    motion_port: int = typer.Option(
        11000, "--motion-port", min=0, max=65535, help="Motion server's TCP port (0: any)."
    ),
    state_port: int = typer.Option(
        11002, "--state-port", min=0, max=65535, help="State server's TCP port (0: any)."
    ),
    state_ms: float | None = typer.Option(
        None,
        "--state-ms",
        min=0.5,
        max=10_000.0,
        help="State period, ms (default: 100 as ABB's stock code; 20 with --paper).",
    ),
    byte_order: ByteOrder = OrderOpt,
    real_size: RealSize = RealOpt,
    profile: Profile = typer.Option(
        "abb", "--profile", help="abb (RAPID servers) or generic (streaming server)."
    ),
    robot: str = RobotOpt,
    latency_ms: float = typer.Option(
        0.0, "--latency-ms", min=0.0, max=10_000.0, help="Motion reply delay, ms."
    ),
    jitter_ms: float = typer.Option(
        0.0,
        "--jitter-ms",
        min=0.0,
        max=10_000.0,
        help="Motion reply jitter: std of a skewed extra delay, ms.",
    ),
    noise_rad: float = typer.Option(
        0.0, "--noise-rad", min=0.0, max=1.0, help="Gaussian noise on reported joints, rad."
    ),
    period_jitter_ms: float = typer.Option(
        0.0,
        "--period-jitter-ms",
        min=0.0,
        max=10_000.0,
        help="State period std, ms (each period drawn afresh, skewed as the paper's).",
    ),
    lag_ms: float = typer.Option(
        0.0, "--lag-ms", min=0.0, max=10_000.0, help="Execution delay after activation, ms."
    ),
    paper: bool = typer.Option(False, "--paper", help="The paper-like controller model."),
    feedback: bool = typer.Option(
        False, "--feedback", help="Also send JOINT_FEEDBACK with the controller time."
    ),
    time_scale: float = typer.Option(
        1.0, "--time-scale", min=0.1, max=100.0, help="Simulated seconds per wall second."
    ),
    bind: str = typer.Option("127.0.0.1", "--bind", help="Address to listen on."),
    replay: Path | None = ReplayOpt,
    speed: float | None = SpeedOpt,
    loop: bool = LoopOpt,
) -> None:
    """Run a simulated ABB controller (RAPID motion and state servers) until Ctrl-C."""
    from robocli.sim.abb.server import PROFILES, AbbSim, ControllerModel

    rate = check_replay(replay, speed, loop)
    check_wire(byte_order, real_size)
    if profile not in PROFILES:
        raise typer.BadParameter(f"--profile is one of {', '.join(PROFILES)}, not {profile!r}")
    if motion_port == state_port != 0:
        raise typer.BadParameter(
            f"--motion-port and --state-port are both {motion_port}: the motion and the state "
            "server each need their own port"
        )
    if replay is not None:
        abb_replay(replay, rate, loop, robot, profile, bind, motion_port, state_port)
        return
    if state_ms is None:
        state_ms = 20.0 if paper else 100.0
    model = (
        ControllerModel.paper()
        if paper
        else ControllerModel(latency_ms, jitter_ms, noise_rad, period_jitter_ms, lag_ms)
    )
    with (
        sigterm_as_interrupt(),
        AbbSim(
            robot,
            profile=profile,
            state_ms=state_ms,
            byteorder=">" if byte_order == "big" else "<",
            real=8 if real_size == 8 else 4,
            time_scale=time_scale,
            model=model,
            feedback=feedback,
        ) as simulator,
    ):
        with listening(bind):
            motion, state = simulator.serve_tcp(bind_address(bind), motion_port, state_port)
        typer.echo(
            f"{simulator.robot.name} ({profile}): motion {motion}, state {state}, "
            f"state every {state_ms:g} ms" + ("" if model.exact else ", model on")
        )
        sys.stdout.flush()
        while True:  # Ctrl-C, SIGTERM: the simulator closes, exit 130
            time.sleep(3600)


# ------------------------------------------------------------------------------ upload arm


def _trajectory(
    robot: str,
    shape: str | None,
    points: int,
    file: Path | None,
    duration: float | None,
    radius: float,
    center: str | None,
) -> TrajectoryLog:
    from robocli.kinematics import load_model
    from robocli.kinematics import trajectory as tr

    if (shape is None) == (file is None):
        raise typer.BadParameter("give --shape or --file")
    if file is not None:
        from robocli.kinematics.trajlog import read_log

        return read_log(file)
    from robocli.commands.kinematics import _floats

    c = _floats(center, 3, "--center")
    model = load_model(robot)
    if shape == "circle":
        return tr.circle(model, points, radius, c, duration=duration)
    if shape == "rectangle":
        return tr.rectangle(model, points, 2 * radius, 1.2 * radius, c, duration=duration)
    raise typer.BadParameter(f"--shape is circle or rectangle, not {shape!r}")


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


@arm_link()
def upload(
    host: str = HostArg,
    shape: Shape | None = typer.Option(None, "--shape", help="circle or rectangle."),
    points: int = count_option(100, "Points of the --shape.", min=1, max=100_000),
    file: Path | None = typer.Option(None, "--file", help="Trajectory log (.json/.csv/.npz)."),
    duration: float | None = duration_option(None, "Shape duration, s."),
    radius: float = typer.Option(0.05, "--radius", min=1e-4, max=5.0, help="Shape size, m."),
    center: str | None = typer.Option(None, "--center", help="Shape centre x,y,z, m."),
    monitor: Path | None = output_option(
        None, "Log the run's states to this file (.json/.csv/.npz)."
    ),
    record_to: Path | None = typer.Option(
        None,
        "--record",
        metavar="FILE.mcap",
        dir_okay=False,
        help="Record this upload's connection (both ports, every frame) to an MCAP file.",
    ),
    ros2: bool = typer.Option(False, "--ros2", help="--record a ROS 2 bag (docs/ros2-bags.md)."),
    overwrite: bool = OverwriteOpt,
    split: bool = typer.Option(False, "--split", help="Upload > 100 points in several parts."),
    stream: bool = typer.Option(False, "--stream", help="Stream (generic servers, not ABB)."),
    link: ArmLink = LINK,
    wait: float = typer.Option(
        600.0,
        "--wait",
        min=0.0,
        max=86_400.0,
        help="Seconds to wait for the end (0: do not wait; the arm moves on).",
    ),
) -> None:
    """Upload a trajectory (download -1..-3, each point acknowledged) and wait for its end."""
    from robocli.devices.arm import StillMoving
    from robocli.kinematics.trajlog import check_writable

    if monitor is not None and wait == 0:
        raise typer.BadParameter("--output logs until the end: give --wait > 0")
    if monitor is not None:
        check_writable(monitor, overwrite)  # before the arm moves: not after the whole run
    traj = _trajectory(link.robot, shape, points, file, duration, radius, center)
    with _recorded(record_to, link, overwrite, ros2) as (rec, listeners), \
            connected(host, link, stream, listeners=listeners) as arm:  # fmt: skip
        if rec is not None:
            rec.add(arm, "arm")
            rec.begin()  # connected: now the file is made
            typer.echo(f"recording to {rec.path}", err=True)
        arm.check_trajectory(traj, split=split or stream)  # before the arm moves at all
        here = arm.wait_for_state().joints
        gap = max(abs(a - float(b)) for a, b in zip(here, traj.positions[0], strict=False))
        if not stream and gap > 1e-3:
            typer.echo("moving to the first point")
            arm.move_to(traj.positions[0])
            arm.wait_until_idle(max(wait, 600.0))
        kept = recording(arm, monitor, overwrite=overwrite) if monitor is not None \
            else contextlib.nullcontext()  # fmt: skip
        with kept:  # the log is written however the run ends
            with _Progress() as progress:
                send = arm.stream if stream else arm.download
                kw: dict[str, Any] = {} if stream else {"split": split}
                sent = send(traj, progress=progress, **kw)
            if wait == 0:  # fire and forget: the activated trajectory runs on
                arm.close(stop=False)
                typer.echo(f"uploaded {sent} points; the arm is moving, not waiting")
                return
            try:
                arm.wait_until_idle(wait)
            except StillMoving:
                arm.close(stop=False)  # --wait bounds the waiting, not the motion
                raise StillMoving(
                    f"uploaded {sent} points; the arm is still moving after "
                    f"{wait:g} s and keeps moving (not waiting longer)"
                ) from None
    typer.echo(f"uploaded {sent} points; arm idle")


@contextlib.contextmanager
def _recorded(path: Path | None, link: ArmLink, overwrite: bool,
              ros2: bool = False) -> Iterator[tuple[Any, dict[str, Any]]]:  # fmt: skip
    """``upload --record``: a recorder (not begun: the file is made once connected) and the
    listeners to connect the arm with, so that both ports are recorded from their first
    byte; ``(None, {})`` without a path. The recording is closed after the arm (its stop
    is recorded) and says what it holds, however the upload ends."""
    if path is None:
        yield None, {}
        return
    from robocli.commands.record import close_recording
    from robocli.io.record import Recorder
    from robocli.io.record.arm import arm_links

    if path.suffix != ".mcap":
        raise typer.BadParameter(f"--record {path}: a recording needs a .mcap name")
    rec = Recorder(
        path, overwrite=overwrite, deferred=True, ros2=ros2
    )  # refused now (and a missing rosbags said): before connecting
    name, links = arm_links(rec, "arm", byte_order=link.byte_order, real_size=link.real_size)
    assert name == "arm"
    start = time.monotonic()
    try:
        yield rec, {port: [raw] for port, raw in links.items()}
    finally:
        with shielded():
            close_recording(rec, time.monotonic() - start)


# ------------------------------------------------------------------------------ monitor, connect


@contextlib.contextmanager
def recording(arm: Arm, out: Path, max_samples: int | None = None, *,
              overwrite: bool = False) -> Iterator[JointRecorder]:  # fmt: skip
    """Record ``arm``'s joint samples (:meth:`Arm.record`) and write them to ``out`` however
    the block ends: its end, Ctrl-C or SIGTERM, a ``--wait`` that ran out, a lost link.
    Says on stderr how many samples went where; the block's own error (its exit code) goes
    on. Ctrl-C and SIGTERM wait while the log is written."""
    from robocli.errors import RobocliError

    rec = arm.record() if max_samples is None else arm.record(max_samples)
    try:
        yield rec
    except BaseException:
        with shielded():
            rec.stop()
            try:
                _write_recording(rec, out, overwrite)
            except RobocliError as exc:  # the block's error is the one to exit with
                typer.echo(f"{out} not written: {exc}", err=True)
        raise
    with shielded():
        rec.stop()
        _write_recording(rec, out, overwrite)


def _write_recording(rec: JointRecorder, out: Path, overwrite: bool) -> None:
    from robocli.kinematics.trajlog import write_log

    log = rec.log()
    write_log(log, out, overwrite)
    typer.echo(f"recorded {len(log)} samples over {log.time[-1] - log.time[0]:.3f} s -> {out}",
               err=True)  # fmt: skip


@arm_link(motion=False)
def monitor(
    host: str = HostArg,
    out: Path = output_option(Path("real.json"), "Log to write (.json/.csv/.npz)."),
    overwrite: bool = OverwriteOpt,
    samples: int | None = count_option(
        None, "States to record (default: until Ctrl-C).", min=2, max=1_000_000
    ),
    duration: float | None = duration_option(
        None, "Seconds to record (a few states).", min=0.5, max=86_400.0
    ),
    link: ArmLink = LINK,
) -> None:
    """Record the state stream (independently of any upload) to a JSON/CSV/NPZ log, for
    --count, --duration or until Ctrl-C; the log is written however it ends."""
    from robocli.kinematics.trajlog import check_writable

    if samples is not None and duration is not None:
        raise typer.BadParameter("give --count or --duration, not both")
    check_writable(out, overwrite)  # before recording: not after the whole --duration
    with connected(host, link) as arm, \
            recording(arm, out, samples and 2 * samples, overwrite=overwrite) as rec:  # fmt: skip
        if samples is None and duration is None:
            typer.echo(f"recording to {out} until Ctrl-C", err=True)
        end = time.monotonic() + (duration if duration is not None else math.inf)
        while time.monotonic() < end and (samples is None or _count(rec) < samples):
            arm.wait_for_state(link.timeout)


def _count(rec: Any) -> int:
    timed = sum(1 for s in rec.samples if s.robot_time is not None)
    return timed or len(rec.samples)


def describe(arm: Arm) -> dict[str, Any]:
    """Joints (deg and rad), TCP pose (flange position in m, roll-pitch-yaw in deg) and
    status of the last state; ``t`` its receive time as Unix time (``t_mono``: on
    ``time.monotonic()``), ``robot_time`` the controller's."""
    from robocli.kinematics.fk import fk

    sample = arm.joints
    assert sample is not None
    pose = fk(arm.robot, list(sample.joints))[0]
    r = pose[:3, :3]  # Z-Y-X Euler angles (yaw about z, pitch about y, roll about x)
    rpy = (math.atan2(r[2, 1], r[2, 2]), math.asin(max(-1.0, min(1.0, -r[2, 0]))),
           math.atan2(r[1, 0], r[0, 0]))  # fmt: skip
    st = arm.status
    return {
        **unix_stamped({"t": sample.t}), "robot_time": sample.robot_time,
        "joints_rad": list(sample.joints),
        "joints_deg": sample.degrees(), "tcp_m": [float(v) for v in pose[:3, 3]],
        "tcp_rpy_deg": [math.degrees(v) for v in rpy],
        "status": st.as_dict() if st is not None else None,
    }  # fmt: skip


def _line(d: dict[str, Any]) -> str:
    """One state in one terminal line (under 100 characters): joints (deg), TCP (m) and
    roll-pitch-yaw (deg), and only the status flags that are set (``--json``: everything)."""
    deg = " ".join(f"{v:.1f}" for v in d["joints_deg"])
    x, y, z = d["tcp_m"]
    roll, pitch, yaw = d["tcp_rpy_deg"]
    st = d["status"] or {}
    flags = [word for key, word in _FLAGS.items() if st.get(key) is True]
    flags += [str(st["mode"])] if st.get("mode") else []
    flags += [f"error {st['error_code']}"] if st.get("error_code") else []
    return (
        f"deg [{deg}]  tcp {x:.3f} {y:.3f} {z:.3f} m  rpy {roll:.0f} {pitch:.0f} {yaw:.0f}"
        f"  {' '.join(flags)}"
    )


#: The status flags a text line shows when set, and their words there.
_FLAGS = {"drives_powered": "powered", "motion_possible": "ready", "in_motion": "moving",
          "in_error": "ERROR", "e_stopped": "E-STOP"}  # fmt: skip


@arm_link(motion=False)
def connect(
    host: str = HostArg,
    once: bool = typer.Option(False, "--once", help="Print one state and exit."),
    json_out: bool = json_option(),
    count: int | None = count_option(None, "Stop after N states.", min=1),
    foxglove: int | None = FoxgloveOpt,
    foxglove_host: str = FoxgloveHostOpt,
    link: ArmLink = LINK,
) -> None:
    """Show the arm's live joints (deg), TCP position and status until q (on a terminal)
    or Ctrl-C (--json: every field, rad too; --foxglove: also to Foxglove, with every
    link's frame)."""
    from robocli.commands._live import live_view
    from robocli.commands._screens import keyboard

    with reader_may_leave(), live_view(foxglove, foxglove_host) as view, \
            connected(host, link) as arm, keyboard() as read_key:  # fmt: skip
        if view is not None:
            view.add(arm)
        arm.wait_for_state()
        shown, last = 0, 0.0
        while True:  # Ctrl-C: exit 130 (the link is closed on the way out)
            d = describe(arm)
            if once:
                print_json(rounded(d)) if json_out else typer.echo(_line(d))
                return
            if json_out:
                print_json_line(rounded(d))
                shown += 1
            elif d["t"] - last >= 0.1:
                typer.echo(_line(d))
                shown, last = shown + 1, d["t"]
            if count is not None and shown >= count:
                return
            if read_key is not None and read_key(0) in ("q", "Q", "esc"):
                return  # as the Pioneer's view
            arm.wait_for_state(link.timeout)
