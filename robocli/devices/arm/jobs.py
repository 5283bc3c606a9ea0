"""What the arm commands do, for a script too: reach a controller by address (or ``sim``),
build a shape's trajectory, upload and run it to its end, keep a joint log however a run
ends, record the state stream for a while.

>>> from robocli.devices.arm import Arm                                  # doctest: +SKIP
>>> from robocli.devices.arm.jobs import KeptLog, run_trajectory, shape_trajectory
>>> with Arm.connect("sim://") as arm, KeptLog(arm, "real.json"):
...     run_trajectory(arm, shape_trajectory("irb120", "circle", 100))

Nothing here prints: what a run has to say goes to ``say`` (default: the log).
"""

from __future__ import annotations

import contextlib
import logging
import math
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import AbstractContextManager
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

from robocli.errors import InvalidArgument, RobocliError
from robocli.running import shielded

if TYPE_CHECKING:
    from robocli.devices.arm import Arm
    from robocli.devices.arm.state import JointRecorder
    from robocli.kinematics.trajlog import TrajectoryLog

log = logging.getLogger("robocli.devices.arm.jobs")

__all__ = ["SIM", "KeptLog", "arm_address", "record_states", "run_trajectory",
           "shape_trajectory"]  # fmt: skip

#: The address of an embedded simulator (see :func:`arm_address`).
SIM = "sim"
#: The embedded simulator's state period, ms: JOINT_FEEDBACK every 5 ms, so that a monitored
#: run validates to the float.
EMBEDDED_STATE_MS = 5.0
Progress = Callable[[int, int], None]


@contextlib.contextmanager
def arm_address(host: str, motion_port: int = 11000, state_port: int = 11002,
                byte_order: str = "little", real_size: int = 4, robot: str = "irb120",
                profile: str = "abb") -> Iterator[tuple[str, int, int]]:  # fmt: skip
    """Yield ``(host, motion_port, state_port)`` for ``host`` (a host name or address,
    ``tcp://`` allowed); for ``sim``, an embedded exact simulator (JOINT_FEEDBACK every
    5 ms) on ephemeral loopback ports, closed afterwards: the ABB RAPID servers, or with
    ``profile="generic"`` an industrial_robot_client-style streaming server (an ABB never
    executes streamed points). A bad host is an :class:`~robocli.transports.InvalidURL`."""
    if host != SIM:
        from robocli.transports import InvalidURL, parse_host

        host = host.removeprefix("tcp://").rstrip("/")
        try:
            host = parse_host(host, what="HOST")
        except InvalidURL as exc:  # the ports have their own options
            ports = "ports: --motion-port, --state-port"
            raise InvalidURL(f"URL {host!r}: {exc.reason} ({ports})", exc.reason) from None
        yield host, motion_port, state_port
        return
    from robocli.sim.abb.server import AbbSim

    with AbbSim(robot, profile=profile, state_ms=EMBEDDED_STATE_MS, feedback=True,
                real=8 if real_size == 8 else 4,
                byteorder=">" if byte_order == "big" else "<") as simulator:  # fmt: skip
        motion, state = simulator.serve_tcp("127.0.0.1", 0, 0)
        yield "127.0.0.1", int(motion.rsplit(":", 1)[1]), int(state.rsplit(":", 1)[1])


def shape_trajectory(robot: str, shape: str, points: int = 100, radius: float = 0.05,
                     center: Sequence[float] | None = None,
                     duration: float | None = None) -> TrajectoryLog:  # fmt: skip
    """The trajectory of ``shape`` for model ``robot`` through IK: a ``circle`` of
    ``radius`` (m), or a ``rectangle`` 2 x 1.2 ``radius``, about ``center`` (x, y, z in m;
    default the work pose's TCP), of ``points`` points over ``duration`` s (default: at
    the model's TCP speed)."""
    from robocli.kinematics import load_model
    from robocli.kinematics import trajectory as tr

    c = None if center is None else list(center)
    model = load_model(robot)
    if shape == "circle":
        return tr.circle(model, points, radius, c, duration=duration)
    if shape == "rectangle":
        return tr.rectangle(model, points, 2 * radius, 1.2 * radius, c, duration=duration)
    raise InvalidArgument(f"--shape is circle or rectangle, not {shape!r}")


def run_trajectory(arm: Arm, traj: TrajectoryLog, *, split: bool = False, stream: bool = False,
                   wait: float = 600.0,
                   progress: Callable[[], AbstractContextManager[Progress]] | None = None,
                   kept: AbstractContextManager[Any] | None = None,
                   say: Callable[[str], None] = log.info) -> int:  # fmt: skip
    """Run ``traj`` on ``arm`` and return the points sent: checked first (before the arm
    moves at all), the arm moved to its first point unless there (not with ``stream``),
    then downloaded (``split``: more than 100 points in several parts) or streamed, each
    point acknowledged (``progress()``: a context giving ``(done, total)`` a call each),
    then waited for up to ``wait`` s. ``kept``: a context around the sending and the
    waiting (a :class:`KeptLog`). ``wait=0``: the arm is left moving and the link closed
    without STOP; a run still moving after ``wait`` is a
    :class:`~robocli.devices.arm.StillMoving`, the arm left moving too."""
    from robocli.devices.arm import StillMoving

    arm.check_trajectory(traj, split=split or stream)
    here = arm.wait_for_state().joints
    gap = max(abs(a - float(b)) for a, b in zip(here, traj.positions[0], strict=False))
    if not stream and gap > 1e-3:
        say("moving to the first point")
        arm.move_to(traj.positions[0])
        arm.wait_until_idle(max(wait, 600.0))
    with kept or contextlib.nullcontext():  # the log is written however the run ends
        with progress() if progress is not None else contextlib.nullcontext() as report:
            kw: dict[str, Any] = {} if stream else {"split": split}
            sent: int = (arm.stream if stream else arm.download)(traj, progress=report, **kw)
        if wait == 0:  # fire and forget: the activated trajectory runs on
            arm.close(stop=False)
            return sent
        try:
            arm.wait_until_idle(wait)
        except StillMoving:
            arm.close(stop=False)  # `wait` bounds the waiting, not the motion
            raise StillMoving(
                f"uploaded {sent} points; the arm is still moving after "
                f"{wait:g} s and keeps moving (not waiting longer)"
            ) from None
    return sent


class KeptLog:
    """Record ``arm``'s joint samples (:meth:`Arm.record`) inside the block and write them
    to ``out`` (.json/.csv/.npz) however it ends: its end, Ctrl-C or SIGTERM (which wait
    while the log is written), an error. After it, :attr:`written` is the log written, or
    :attr:`error` why it was not when the block had its own error (which goes on; else the
    write's error is raised)."""

    def __init__(self, arm: Arm, out: str | Path, max_samples: int | None = None, *,
                 overwrite: bool = False) -> None:  # fmt: skip
        self.arm, self.out, self.overwrite = arm, Path(out), overwrite
        self.max_samples = max_samples
        self.written: TrajectoryLog | None = None
        self.error: RobocliError | None = None

    def __enter__(self) -> JointRecorder:
        arm = self.arm
        self.recorder = arm.record() if self.max_samples is None else arm.record(self.max_samples)
        return self.recorder

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:  # fmt: skip
        from robocli.kinematics.trajlog import write_log

        with shielded():
            self.recorder.stop()
            try:
                written = self.recorder.log()
                write_log(written, self.out, self.overwrite)
                self.written = written
            except RobocliError as error:  # the block's own error is the one to go on
                if kind is None:
                    raise
                self.error = error
        if self.written is not None:
            log.info("recorded %d samples -> %s", len(self.written), self.out)


def record_states(arm: Arm, recorder: JointRecorder, count: int | None = None,
                  duration: float | None = None, timeout: float = 5.0) -> None:  # fmt: skip
    """Wait for states until ``recorder`` holds ``count`` timed samples (those with the
    controller's time; else all) or ``duration`` s have passed (neither: until Ctrl-C)."""
    end = time.monotonic() + (duration if duration is not None else math.inf)
    while time.monotonic() < end and (count is None or _count(recorder.samples) < count):
        arm.wait_for_state(timeout)


def _count(samples: Iterable[Any]) -> int:
    listed = list(samples)
    timed = sum(1 for s in listed if s.robot_time is not None)
    return timed or len(listed)
