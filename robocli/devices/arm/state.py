"""What the state port says, as Python values: joint samples and the status record.

Also the preparation of a trajectory for upload (:func:`prepare`): points and durations from
a :class:`~robocli.kinematics.trajlog.TrajectoryLog`, checked against the robot model before
anything is sent.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from robocli.errors import EXIT_FAILURE, InvalidArgument, RobocliError, TimeoutError
from robocli.kinematics.model import RobotModel
from robocli.kinematics.trajectory import check_limits
from robocli.kinematics.trajlog import TrajectoryLog

__all__ = [
    "ABB_MAX_POINTS", "ArmStatus", "JointRecorder", "JointSample", "Point", "TooFewSamples",
    "prepare", "split_points",
]  # fmt: skip

ABB_MAX_POINTS = 100  #: the ABB RAPID server's buffer; it drops the rest silently
DEFAULT_FIRST_DURATION = 10.0  #: industrial_robot_client's first-point duration (s)

_MODES = {1: "MANUAL", 2: "AUTO"}


def _tri(value: int) -> bool | None:
    """TriState -> True / False / None (unknown)."""
    return None if value < 0 else bool(value)


@dataclass(frozen=True, slots=True)
class JointSample:
    """Joint positions (rad) received at ``t`` (``time.monotonic()`` on this computer).

    ``robot_time``: the controller's own clock (s) when the message carried one (JOINT_FEEDBACK
    with its TIME bit), else ``None``. ``source``: ``"joint_position"`` or ``"joint_feedback"``.
    """

    t: float
    joints: tuple[float, ...]
    robot_time: float | None = None
    source: str = "joint_position"

    def degrees(self) -> list[float]:
        return [math.degrees(v) for v in self.joints]


@dataclass(frozen=True)
class ArmStatus:
    """The STATUS message. TriStates are ``True``/``False``/``None`` (unknown)."""

    t: float
    drives_powered: bool | None
    e_stopped: bool | None
    in_error: bool | None
    in_motion: bool | None
    motion_possible: bool | None
    mode: str
    error_code: int

    @classmethod
    def from_body(cls, body: dict[str, Any], t: float) -> ArmStatus:
        return cls(
            t=t, drives_powered=_tri(body["drives_powered"]), e_stopped=_tri(body["e_stopped"]),
            in_error=_tri(body["in_error"]), in_motion=_tri(body["in_motion"]),
            motion_possible=_tri(body["motion_possible"]),
            mode=_MODES.get(int(body["mode"]), "UNKNOWN"), error_code=int(body["error_code"]),
        )  # fmt: skip

    def as_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__ if k != "t"}


@dataclass(frozen=True)
class Point:
    """One JOINT_TRAJ_PT: joints (rad), velocity (fraction of max), duration (s)."""

    joints: tuple[float, ...]
    velocity: float
    duration: float


def prepare(
    model: RobotModel,
    traj: TrajectoryLog | tuple[npt.ArrayLike, npt.ArrayLike],
    q_now: npt.ArrayLike | None,
    first_duration: float | None,
) -> list[Point]:
    """Points for ``traj`` (a log, or ``(times, positions)``), checked against ``model``:
    finite values, increasing times, joints within range, segment speeds within the limits.

    The first point's duration is ``first_duration`` when given; else the time to reach it
    from ``q_now`` at a quarter of the speed limits (at least 0.5 s); else 10 s, as
    industrial_robot_client. Raises :class:`InvalidArgument` or
    :class:`~robocli.kinematics.LimitError` (both exit 2) before anything is sent.
    """
    if not isinstance(traj, TrajectoryLog):
        try:
            traj = TrajectoryLog.from_positions(*traj)
        except (ValueError, TypeError) as exc:
            raise InvalidArgument(f"trajectory: {exc}") from None
    if traj.n_joints != model.n_joints:
        raise InvalidArgument(f"trajectory has {traj.n_joints} joints; {model.name} has "
                              f"{model.n_joints}")  # fmt: skip
    t, q = traj.time, traj.positions
    if len(traj) < 1 or not (np.all(np.isfinite(t)) and np.all(np.isfinite(q))):
        raise InvalidArgument("trajectory: empty, or a time or joint is NaN/infinite")
    if np.any(np.diff(t) <= 0):
        raise InvalidArgument("trajectory: times must increase strictly")
    check_limits(model, TrajectoryLog(t, q, np.zeros_like(q)))
    dt = np.diff(t)
    if dt.size:
        speed = np.abs(np.diff(q, axis=0)) / dt[:, None]
        fraction = np.max(speed / model.max_speed, axis=1)
        if np.any(fraction > 1 + 1e-9):
            k = int(np.argmax(fraction))
            raise InvalidArgument(
                f"trajectory: segment {k}->{k + 1} needs {100 * fraction[k]:.0f}% of a joint's "
                f"speed limit on {model.name} (slow it down)"
            )
    else:
        fraction = np.zeros(0)
    if first_duration is None:
        if q_now is None:
            first_duration = DEFAULT_FIRST_DURATION
        else:
            gap = np.abs(q[0] - np.asarray(q_now, dtype=float)[: model.n_joints])
            first_duration = max(0.5, float(np.max(gap / (0.25 * model.max_speed))))
    elif not (math.isfinite(first_duration) and first_duration > 0):
        raise InvalidArgument(f"first_duration must be > 0 s, not {first_duration}")
    durations = [float(first_duration), *(float(d) for d in dt)]
    velocities = [0.0, *(min(1.0, float(f)) for f in fraction)]
    return [Point(tuple(float(v) for v in q[i]), velocities[i], durations[i])
            for i in range(len(traj))]  # fmt: skip


def split_points(points: list[Point], size: int = ABB_MAX_POINTS) -> list[list[Point]]:
    """Trajectories of at most ``size`` points; each after the first starts at the previous
    one's last point (the server skips it: the arm is already there)."""
    if len(points) <= size:
        return [points]
    out = [points[:size]]
    i = size
    while i < len(points):
        last = out[-1][-1]
        chunk = [Point(last.joints, 0.0, 0.1), *points[i : i + size - 1]]
        out.append(chunk)
        i += size - 1
    return out


class TooFewSamples(TimeoutError):
    """:meth:`JointRecorder.log` of a recording shorter than two samples: the controller was
    reached (exit 1, not an unreachable one's 3); record for longer."""

    exit_code = EXIT_FAILURE


class JointRecorder:
    """Joint samples collected from ``Arm.record()`` until :meth:`stop` (bounded).

    :meth:`log` builds a :class:`~robocli.kinematics.trajlog.TrajectoryLog`: on the
    controller's clock when its messages carry one (JOINT_FEEDBACK), else on this computer's
    receive times, counted from the first sample recorded (time 0, as a planned trajectory's
    start), that clock's reading there kept as the log's ``origin``.
    """

    def __init__(self, arm: Any, max_samples: int) -> None:
        self._arm = arm
        self.samples: deque[JointSample] = deque(maxlen=max_samples)
        arm.add_listener(self.samples.append, kind="samples")

    def stop(self, settle: float = 1.0) -> None:
        """Stop recording. The state in flight is waited for first (one more joint sample,
        at most ``settle`` s; not on a link that is gone): a controller sends its
        JOINT_FEEDBACK after the STATUS that ended a wait for idle, and that last sample of
        the motion belongs in the log."""
        if settle > 0 and self._arm.alive:
            try:
                self._arm.wait_for_state(settle)
            except RobocliError:  # no state came, or the link went: keep what was recorded
                pass
        self._arm.remove_listener(self.samples.append, kind="samples")

    def log(self) -> TrajectoryLog:
        from robocli.kinematics.fk import fk_positions

        samples = list(self.samples)
        timed = [s for s in samples if s.robot_time is not None]
        if timed:  # on the controller's clock
            pairs = [(float(s.robot_time), s) for s in timed]  # type: ignore[arg-type]
        else:  # on this computer's receive times (one read may bring several: keep the last)
            pairs = [(s.t, s) for s in samples if s.source == "joint_position"]
        kept: list[tuple[float, JointSample]] = []
        for t, s in pairs:  # strictly increasing times
            if not kept or t > kept[-1][0]:
                kept.append((t, s))
            elif t == kept[-1][0]:
                kept[-1] = (t, s)
        times = [t for t, _ in kept]
        samples = [s for _, s in kept]
        if len(samples) < 2:
            raise TooFewSamples(
                f"{len(samples)} joint sample(s) recorded: a log needs two; "
                "record for longer than two state periods"
            )
        q = [s.joints for s in samples]
        origin = times[0]
        log = TrajectoryLog.from_positions([t - origin for t in times], q,
                                           fk_positions(self._arm.robot, q))  # fmt: skip
        return replace(log, origin=origin)
