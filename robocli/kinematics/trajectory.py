"""Trajectories sampled ideally ("simulated"): shapes in a plane, point-to-point moves in
joint or Cartesian space, and user waypoints, each returned as a checked :class:`TrajectoryLog`.

Cartesian shapes keep the flange orientation of their start pose (default: the model's work
pose) and go through :func:`~robocli.kinematics.ik.ik_path`. Timing comes from a TCP speed
(m/s) or a total duration (s); joint velocities come from finite differences; joint ranges
and speed limits are checked with an error that names the joint and the point.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from robocli.kinematics.errors import KinematicsError, LimitError
from robocli.kinematics.fk import fk, fk_positions
from robocli.kinematics.ik import ik_path
from robocli.kinematics.model import FloatArray, RobotModel
from robocli.kinematics.trajlog import TrajectoryLog

MAX_POINTS = 100_000
DEFAULT_POINTS = 100
DEFAULT_SPEED = 0.05  # m/s along the TCP path
PLANES = {"xy": (0, 1), "yz": (1, 2), "xz": (0, 2)}
_LIMIT_TOL = 1e-9


def _check_points(n: int) -> None:
    if not 2 <= n <= MAX_POINTS:
        raise KinematicsError(f"a trajectory has 2 to {MAX_POINTS} points, not {n}")


def _start(model: RobotModel, q_start: npt.ArrayLike | None) -> FloatArray:
    q0 = np.asarray(model.work if q_start is None else q_start, dtype=float)
    if q0.shape != (model.n_joints,) or not np.all(np.isfinite(q0)):
        raise KinematicsError(f"{model.name}: a start pose is {model.n_joints} finite angles")
    return q0


def plane_points(center: npt.ArrayLike, plane: str, u: FloatArray, v: FloatArray) -> FloatArray:
    """Points ``center + u e_a + v e_b`` for the plane's two base axes (``xy``, ``yz``, ``xz``)."""
    if plane not in PLANES:
        raise KinematicsError(f"unknown plane {plane!r}; use one of {', '.join(PLANES)}")
    ia, ib = PLANES[plane]
    pts = np.repeat(np.asarray(center, dtype=float)[None], u.shape[0], axis=0)
    pts[:, ia] += u
    pts[:, ib] += v
    return pts


def circle_path(center: npt.ArrayLike, radius: float, n: int, plane: str = "xy") -> FloatArray:
    """``n`` points on a closed circle (first point repeated last), counter-clockwise."""
    _check_points(n)
    if not radius > 0:
        raise KinematicsError("the circle radius must be positive")
    phi = np.linspace(0.0, 2 * math.pi, n)
    return plane_points(center, plane, radius * np.cos(phi), radius * np.sin(phi))


def rectangle_path(
    center: npt.ArrayLike, width: float, height: float, n: int, plane: str = "xy"
) -> FloatArray:
    """``n`` points spread evenly by arc length on a closed rectangle (corners exact when
    they fall on a sample), starting at a corner."""
    _check_points(n)
    if not (width > 0 and height > 0):
        raise KinematicsError("the rectangle width and height must be positive")
    corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1], [-1, -1]], dtype=float)
    corners *= [width / 2, height / 2]
    seg = np.linalg.norm(np.diff(corners, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    s = np.linspace(0.0, cum[-1], n)
    u = np.interp(s, cum, corners[:, 0])
    v = np.interp(s, cum, corners[:, 1])
    return plane_points(center, plane, u, v)


def quintic(n: int) -> FloatArray:
    """Quintic blend 0 -> 1 over ``n`` samples evenly spaced in time (zero end velocity and
    acceleration)."""
    tau = np.linspace(0.0, 1.0, n)
    return np.asarray(tau**3 * (10 - 15 * tau + 6 * tau**2), dtype=float)


def times_for(
    path: FloatArray, speed: float | None, duration: float | None, uniform: bool = False
) -> FloatArray:
    """Sample times (s, from 0): constant TCP ``speed`` along ``path`` (N x 3), or the path
    stretched to ``duration``; ``uniform`` spaces samples evenly in time instead."""
    if speed is not None and duration is not None:
        raise KinematicsError("give a speed or a duration, not both")
    if speed is not None and not (0 < speed <= 10):
        raise KinematicsError(f"speed must be in (0, 10] m/s, not {speed}")
    if duration is not None and not (0 < duration <= 86_400):
        raise KinematicsError(f"duration must be in (0, 86400] s, not {duration}")
    steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
    length = float(np.sum(steps))
    if duration is None:
        if length <= 0:
            raise KinematicsError("the TCP does not move along this path: give a duration")
        duration = length / (DEFAULT_SPEED if speed is None else speed)
    if uniform or length <= 0:
        return np.linspace(0.0, duration, path.shape[0])
    cum = np.concatenate([[0.0], np.cumsum(steps)])
    t = cum / length * duration
    if np.any(np.diff(t) <= 0):
        raise KinematicsError("two consecutive points are equal: the path has no direction there")
    return np.asarray(t, dtype=float)


def simulate(model: RobotModel, time: FloatArray, q: FloatArray) -> TrajectoryLog:
    """Sample joint positions ideally: velocities by finite differences, TCP by FK; check
    the joint ranges and speed limits."""
    log = TrajectoryLog.from_positions(time, q, fk_positions(model, q))
    check_limits(model, log)
    return log


def check_limits(model: RobotModel, log: TrajectoryLog) -> None:
    """Raise :class:`LimitError` at the first joint out of range or over its speed limit."""
    if log.n_joints != model.n_joints:
        raise LimitError(f"{model.name} has {model.n_joints} joints, the log has {log.n_joints}")
    lo, hi = model.limits[:, 0] - _LIMIT_TOL, model.limits[:, 1] + _LIMIT_TOL
    bad = (log.positions < lo) | (log.positions > hi)
    if np.any(bad):
        k, j = (int(v) for v in np.argwhere(bad)[0])
        raise LimitError(
            f"joint {j + 1} at point {k} is {math.degrees(log.positions[k, j]):.2f} deg, beyond "
            f"its range [{math.degrees(lo[j]):.0f}, {math.degrees(hi[j]):.0f}] deg on {model.name}"
        )
    fast = np.abs(log.velocities) > model.max_speed * (1 + 1e-9)
    if np.any(fast):
        k, j = (int(v) for v in np.argwhere(fast)[0])
        raise LimitError(
            f"joint {j + 1} at point {k} needs {math.degrees(abs(log.velocities[k, j])):.1f} "
            f"deg/s, over its {math.degrees(model.max_speed[j]):.0f} deg/s limit on "
            f"{model.name} (slow down: a lower speed or a longer duration)"
        )


def cartesian(
    model: RobotModel,
    points: npt.ArrayLike,
    q_start: npt.ArrayLike | None = None,
    speed: float | None = None,
    duration: float | None = None,
    time: npt.ArrayLike | None = None,
    uniform: bool = False,
) -> TrajectoryLog:
    """Flange positions (N x 3 m) at the start pose's orientation, through IK, timed."""
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise KinematicsError("Cartesian points are N rows of x, y, z (m)")
    _check_points(pts.shape[0])
    q0 = _start(model, q_start)
    poses = np.repeat(fk(model, q0), pts.shape[0], axis=0)
    poses[:, :3, 3] = pts
    q = ik_path(model, poses, q0)
    t = (
        np.asarray(time, dtype=float)
        if time is not None
        else times_for(pts, speed, duration, uniform)
    )
    return simulate(model, t, q)


def circle(
    model: RobotModel,
    n: int = DEFAULT_POINTS,
    radius: float = 0.05,
    center: npt.ArrayLike | None = None,
    plane: str = "xy",
    q_start: npt.ArrayLike | None = None,
    speed: float | None = None,
    duration: float | None = None,
) -> TrajectoryLog:
    """A closed circle of ``n`` points around ``center`` (default: the start pose's TCP)."""
    q0 = _start(model, q_start)
    c = fk_positions(model, q0)[0] if center is None else np.asarray(center, dtype=float)
    return cartesian(model, circle_path(c, radius, n, plane), q0, speed, duration)


def rectangle(
    model: RobotModel,
    n: int = DEFAULT_POINTS,
    width: float = 0.10,
    height: float = 0.06,
    center: npt.ArrayLike | None = None,
    plane: str = "xy",
    q_start: npt.ArrayLike | None = None,
    speed: float | None = None,
    duration: float | None = None,
) -> TrajectoryLog:
    """A closed rectangle of ``n`` points around ``center`` (default: the start pose's TCP)."""
    q0 = _start(model, q_start)
    c = fk_positions(model, q0)[0] if center is None else np.asarray(center, dtype=float)
    return cartesian(model, rectangle_path(c, width, height, n, plane), q0, speed, duration)


def ptp_joint(
    model: RobotModel,
    q_goal: npt.ArrayLike,
    n: int = DEFAULT_POINTS,
    q_start: npt.ArrayLike | None = None,
    speed: float | None = None,
    duration: float | None = None,
) -> TrajectoryLog:
    """Joint-space move with a quintic profile; ``speed`` is the mean TCP speed."""
    _check_points(n)
    q0 = _start(model, q_start)
    q1 = _start(model, q_goal)
    q = q0 + quintic(n)[:, None] * (q1 - q0)
    return simulate(model, times_for(fk_positions(model, q), speed, duration, True), q)


def ptp_cartesian(
    model: RobotModel,
    goal: npt.ArrayLike,
    n: int = DEFAULT_POINTS,
    q_start: npt.ArrayLike | None = None,
    speed: float | None = None,
    duration: float | None = None,
) -> TrajectoryLog:
    """Straight TCP line to ``goal`` (m) with a quintic profile along it, through IK."""
    _check_points(n)
    q0 = _start(model, q_start)
    p0 = fk_positions(model, q0)[0]
    p1 = np.asarray(goal, dtype=float)
    if p1.shape != (3,) or not np.all(np.isfinite(p1)):
        raise KinematicsError("a Cartesian goal is x, y, z in metres")
    pts = p0 + quintic(n)[:, None] * (p1 - p0)
    return cartesian(model, pts, q0, speed, duration, uniform=True)


def waypoints(
    model: RobotModel,
    joints: npt.ArrayLike | None = None,
    points: npt.ArrayLike | None = None,
    time: npt.ArrayLike | None = None,
    q_start: npt.ArrayLike | None = None,
    speed: float | None = None,
    duration: float | None = None,
) -> TrajectoryLog:
    """User waypoints: joint rows (rad) or flange positions (m), timed by ``time`` (s) when
    given, else by speed or duration."""
    if (joints is None) == (points is None):
        raise KinematicsError("waypoints are joint angles or Cartesian points, not both")
    t = None if time is None else np.asarray(time, dtype=float)
    if t is not None and (t.ndim != 1 or np.any(np.diff(t) <= 0) or not np.all(np.isfinite(t))):
        raise KinematicsError("waypoint times must be finite and increasing")
    if points is not None:
        pts = np.asarray(points, dtype=float)
        if t is not None and t.shape[0] != pts.shape[0]:
            raise KinematicsError("one time per waypoint")
        return cartesian(model, pts, q_start, speed, duration, time=t)
    q = np.asarray(joints, dtype=float)
    if q.ndim != 2 or q.shape[1] != model.n_joints:
        raise KinematicsError(f"{model.name}: joint waypoints are rows of {model.n_joints} angles")
    _check_points(q.shape[0])
    if not np.all(np.isfinite(q)):
        raise KinematicsError("a joint waypoint holds a NaN or an infinity")
    if t is None:
        t = times_for(fk_positions(model, q), speed, duration)
    elif t.shape[0] != q.shape[0]:
        raise KinematicsError("one time per waypoint")
    return simulate(model, t, q)
