"""Inverse kinematics: closed form for spherical-wrist 6R arms, damped least squares otherwise.

Along a path each point takes the solution (branch, and joint turn for joints with more than
one turn of range) closest to the previous point, so Cartesian paths stay continuous.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterator

import numpy as np
import numpy.typing as npt

from robocli.kinematics.errors import KinematicsError, UnreachableError
from robocli.kinematics.fk import fk
from robocli.kinematics.model import FloatArray, RobotModel

log = logging.getLogger("robocli.kinematics.ik")

MAX_PATH_POINTS = 1_000_000
_EPS_REACH = 1e-10
_EPS_WRIST = 1e-9
_SHIFTS = np.array([-2 * math.pi, 0.0, 2 * math.pi])
_DLS_TOL = 1e-13
_RESTARTS = 24
_DLS_ITERS = 100


def _rz(theta: FloatArray) -> FloatArray:
    c, s = np.cos(theta), np.sin(theta)
    out = np.zeros(theta.shape + (3, 3))
    out[..., 0, 0], out[..., 0, 1] = c, -s
    out[..., 1, 0], out[..., 1, 1] = s, c
    out[..., 2, 2] = 1.0
    return out


def _rx(alpha: float) -> FloatArray:
    c, s = math.cos(alpha), math.sin(alpha)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def analytic_solutions(model: RobotModel, poses: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
    """All closed-form solutions of flange poses (N x 4 x 4) of a spherical-wrist 6R model.

    Returns joint angles N x 8 x 6 (rad, wrapped to [-pi, pi]) for the 2 shoulder x 2 elbow
    x 2 wrist branches, and an N x 8 mask of the branches that reach the target.
    """
    if not model.spherical_wrist:
        raise KinematicsError(f"{model.name} has no spherical wrist: use damped least squares")
    t = np.asarray(poses, dtype=float).reshape(-1, 4, 4)
    a, d, al = model.a, model.d, model.alpha
    rot, p = t[:, :3, :3], t[:, :3, 3]
    z5 = rot[:, :, 1] * math.sin(al[5]) + rot[:, :, 2] * math.cos(al[5])
    pw = p - d[5] * z5
    s1a = math.sin(al[0])
    e = -(d[1] + d[2]) * s1a
    rho = np.hypot(pw[:, 0], pw[:, 1])
    phi = np.arctan2(pw[:, 1], pw[:, 0])
    ok_shoulder = rho >= abs(e) - _EPS_REACH
    asn = np.arcsin(np.clip(e / np.where(rho > 0, rho, 1.0), -1.0, 1.0))
    th1 = np.stack([phi - asn, phi - (math.pi - asn)], axis=1)  # N x 2
    x1 = np.cos(th1) * pw[:, None, 0] + np.sin(th1) * pw[:, None, 1] - a[0]
    y1 = np.broadcast_to(((pw[:, 2] - d[0]) * s1a)[:, None], x1.shape)
    big_l = math.hypot(a[2], d[3])
    phi3 = math.atan2(-d[3] * math.sin(al[2]), a[2])
    c = (x1**2 + y1**2 - a[1] ** 2 - big_l**2) / (2 * a[1] * big_l)
    ok_elbow = np.abs(c) <= 1 + _EPS_REACH
    beta = np.arccos(np.clip(c, -1.0, 1.0))
    beta = np.stack([beta, -beta], axis=2)  # N x 2 x 2
    th2 = np.arctan2(y1, x1)[..., None] - np.arctan2(
        big_l * np.sin(beta), a[1] + big_l * np.cos(beta)
    )
    th3 = beta - phi3
    th1b = np.broadcast_to(th1[..., None], th2.shape)
    r03 = (_rz(th1b) @ _rx(al[0])) @ (_rz(th2) @ _rx(al[1])) @ (_rz(th3) @ _rx(al[2]))
    m = np.swapaxes(r03, -1, -2) @ (rot @ _rx(al[5]).T)[:, None, None]  # N x 2 x 2 x 3 x 3
    s4, s5 = math.sin(al[3]), math.sin(al[4])
    c5 = np.clip(-m[..., 2, 2] * s4 * s5, -1.0, 1.0)
    sn5 = np.sqrt(1.0 - c5**2)
    sn5 = np.stack([sn5, -sn5], axis=-1)  # N x 2 x 2 x 2
    c5 = np.broadcast_to(c5[..., None], sn5.shape)
    m = np.broadcast_to(m[..., None, :, :], sn5.shape + (3, 3))
    sg = np.where(sn5 >= 0, 1.0, -1.0)
    th4 = np.arctan2(m[..., 1, 2] * s5 * sg, m[..., 0, 2] * s5 * sg)
    th6 = np.arctan2(-m[..., 2, 1] * s4 * sg, m[..., 2, 0] * s4 * sg)
    singular = np.abs(sn5) < _EPS_WRIST
    if np.any(singular):
        th4 = np.where(singular, 0.0, th4)
        th6 = np.where(singular, _singular_th6(m, c5, s4, s5, th4), th6)
    th5 = np.arctan2(sn5, c5)
    shape = sn5.shape
    theta = np.stack(
        [
            np.broadcast_to(th1[:, :, None, None], shape),
            np.broadcast_to(th2[..., None], shape),
            np.broadcast_to(th3[..., None], shape),
            th4,
            th5,
            th6,
        ],
        axis=-1,
    ).reshape(-1, 8, 6)
    q = _wrap(theta - model.offset)
    valid = ok_shoulder[:, None, None, None] & ok_elbow[:, :, None, None]
    valid = valid & np.ones(shape, dtype=bool)
    return q, valid.reshape(-1, 8)


def _singular_th6(
    m: FloatArray, c5: FloatArray, s4: float, s5: float, th4: FloatArray
) -> FloatArray:
    """Wrist axes 4 and 6 aligned: with theta4 given, Rz(theta6) = A0 Rz(theta4)^T M."""
    a0 = np.stack([c5, -s4 * s5 * np.ones_like(c5)], axis=-1)
    r = np.swapaxes(_rz(th4), -1, -2) @ m
    return np.arctan2(a0[..., 1] * r[..., 1, 0], a0[..., 0] * r[..., 0, 0])


def _wrap(x: FloatArray) -> FloatArray:
    return np.asarray((x + math.pi) % (2 * math.pi) - math.pi, dtype=float)


def _closest(
    model: RobotModel, cands: FloatArray, prev: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """For candidates B x n, pick each joint's turn (+-2 pi) inside the limits closest to
    ``prev``; return the candidates and their squared distance (inf when a joint fits no turn)."""
    lo, hi = model.limits[:, 0], model.limits[:, 1]
    turns = cands[..., None] + _SHIFTS  # B x n x 3
    fits = (turns >= lo[:, None] - 1e-12) & (turns <= hi[:, None] + 1e-12)
    dist = np.where(fits, np.abs(turns - prev[:, None]), np.inf)
    chosen = cands + _SHIFTS[np.argmin(dist, axis=-1)]
    gap = np.min(dist, axis=-1)
    return chosen, np.sum(gap * gap, axis=-1)


def ik_path(
    model: RobotModel, poses: npt.ArrayLike, q_start: npt.ArrayLike | None = None
) -> FloatArray:
    """Joint angles (N x n rad) reaching flange poses N x 4 x 4 in order, each point on the
    solution closest to the previous one (the first closest to ``q_start``, default the
    model's work pose). Raises :class:`UnreachableError` naming the first bad point."""
    t = np.asarray(poses, dtype=float).reshape(-1, 4, 4)
    if t.shape[0] > MAX_PATH_POINTS:
        raise KinematicsError(f"at most {MAX_PATH_POINTS} points per path, got {t.shape[0]}")
    if not np.all(np.isfinite(t)):
        bad = int(np.argmax(~np.all(np.isfinite(t.reshape(t.shape[0], -1)), axis=1)))
        raise UnreachableError(f"point {bad}: target holds a NaN or an infinity", index=bad)
    prev = np.asarray(model.work if q_start is None else q_start, dtype=float).copy()
    out = np.empty((t.shape[0], model.n_joints))
    if model.spherical_wrist:
        sols, valid = analytic_solutions(model, t)
        for k in range(t.shape[0]):
            cands, dist = _closest(model, sols[k], prev)
            dist = np.where(valid[k], dist, np.inf)
            best = int(np.argmin(dist))
            if not np.isfinite(dist[best]):
                raise _unreachable(model, t, k, bool(np.any(valid[k])))
            prev = _fix_singular_wrist(model, t[k], cands[best], prev)
            out[k] = prev
        return out
    for k in range(t.shape[0]):
        prev = _dls_with_restarts(model, t[k], prev, k)
        out[k] = prev
    return out


def ik(model: RobotModel, pose: npt.ArrayLike, q_near: npt.ArrayLike | None = None) -> FloatArray:
    """Joint angles (n rad) reaching one flange pose (4 x 4), closest to ``q_near``."""
    out: FloatArray = ik_path(model, np.asarray(pose, dtype=float)[None], q_near)[0]
    return out


def _fix_singular_wrist(
    model: RobotModel, target: FloatArray, q: FloatArray, prev: FloatArray
) -> FloatArray:
    """At a wrist singularity only theta4 + theta6 is defined: keep joint 4 where it was."""
    if abs(math.sin(q[4] + model.offset[4])) >= _EPS_WRIST or not model.spherical_wrist:
        return q
    fixed = q.copy()
    fixed[3] = prev[3]
    # solve joint 6 for the kept joint 4 by one exact rotation comparison
    r_now = fk(model, fixed)[0, :3, :3]
    err = r_now.T @ target[:3, :3]
    fixed[5] += math.atan2(err[1, 0], err[0, 0])
    cands, dist = _closest(model, fixed[None], prev)
    return cands[0] if np.isfinite(dist[0]) else q


def _unreachable(
    model: RobotModel, t: FloatArray, k: int, reach: bool, index: int | None = None
) -> UnreachableError:
    pos = tuple(float(v) for v in t[k, :3, 3])
    k = k if index is None else index
    why = (
        f"every solution leaves the joint limits of {model.name}"
        if reach
        else f"outside the workspace of {model.name}"
    )
    where = "({:.4f}, {:.4f}, {:.4f}) m".format(*pos)
    return UnreachableError(
        f"point {k} at {where} is unreachable: {why}", index=k, position=(pos[0], pos[1], pos[2])
    )


def _pose_and_jacobian(model: RobotModel, q: FloatArray) -> tuple[FloatArray, FloatArray]:
    """One pose in plain floats (NumPy's per-call overhead dominates at N = 1): the flange
    pose 4 x 4 and the geometric Jacobian 6 x n."""
    r = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]  # rows of the rotation
    p = [0.0, 0.0, 0.0]
    zs, origins = [], []
    for i in range(model.n_joints):
        zs.append((r[0][2], r[1][2], r[2][2]))
        origins.append((p[0], p[1], p[2]))
        th = float(q[i]) + float(model.offset[i])
        ct, st = math.cos(th), math.sin(th)
        ca, sa = math.cos(float(model.alpha[i])), math.sin(float(model.alpha[i]))
        a, d = float(model.a[i]), float(model.d[i])
        for row in range(3):
            x, y, z = r[row]
            nx = x * ct + y * st
            ny = y * ct - x * st
            p[row] += d * z + a * nx
            r[row] = [nx, ny * ca + z * sa, z * ca - ny * sa]
    pose = np.eye(4)
    pose[:3, :3] = r
    pose[:3, 3] = p
    jac = np.empty((6, model.n_joints))
    for i, (ax, o) in enumerate(zip(zs, origins, strict=True)):
        dx, dy, dz = p[0] - o[0], p[1] - o[1], p[2] - o[2]
        jac[:, i] = (
            ax[1] * dz - ax[2] * dy,
            ax[2] * dx - ax[0] * dz,
            ax[0] * dy - ax[1] * dx,
            ax[0],
            ax[1],
            ax[2],
        )
    return pose, jac


def _error(pose: FloatArray, target: FloatArray) -> FloatArray:
    """Position error (m) and rotation error (axis x angle, rad) from ``pose`` to ``target``."""
    return np.concatenate(
        [target[:3, 3] - pose[:3, 3], _log_rotation(target[:3, :3] @ pose[:3, :3].T)]
    )


def _log_rotation(r: FloatArray) -> FloatArray:
    """Axis x angle of a rotation matrix (exact also near pi, unlike the cross-product error)."""
    cos = max(-1.0, min(1.0, (float(np.trace(r)) - 1.0) / 2.0))
    angle = math.acos(cos)
    vee = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    if angle < 1e-6:
        return 0.5 * vee
    if math.pi - angle > 1e-6:
        return vee * (angle / (2.0 * math.sin(angle)))
    axis = np.sqrt(np.maximum((np.diag(r) + 1.0) / 2.0, 0.0))
    k = int(np.argmax(axis))
    axis = (r[:, k] + np.eye(3)[k]) / 2.0 / axis[k]
    return np.asarray(axis / np.linalg.norm(axis) * angle, dtype=float)


def dls(model: RobotModel, target: npt.ArrayLike, q_seed: npt.ArrayLike) -> FloatArray | None:
    """Damped least squares (Levenberg-Marquardt damping) from ``q_seed``; ``None`` when it
    does not converge to 1e-12 within the joint limits."""
    t = np.asarray(target, dtype=float)
    q = np.asarray(q_seed, dtype=float).copy()
    pose, jac = _pose_and_jacobian(model, q)
    err = _error(pose, t)
    cost = float(err @ err)
    mu = 1e-3
    eye = np.eye(6)
    for _ in range(_DLS_ITERS):
        if cost < _DLS_TOL**2:
            break
        q_new = q + jac.T @ np.linalg.solve(jac @ jac.T + mu * eye, err)
        pose_new, jac_new = _pose_and_jacobian(model, q_new)
        err_new = _error(pose_new, t)
        cost_new = float(err_new @ err_new)
        if cost_new < cost:
            q, jac, err, cost = q_new, jac_new, err_new, cost_new
            mu = max(mu / 10.0, 1e-12)
        else:
            mu *= 10.0
            if mu > 1e4:
                break
    if cost >= 1e-24:
        return None
    cands, dist = _closest(model, _wrap(q)[None], np.asarray(q_seed, dtype=float))
    return cands[0] if np.isfinite(dist[0]) else None


def _dls_with_restarts(
    model: RobotModel, target: FloatArray, prev: FloatArray, k: int
) -> FloatArray:
    def seeds() -> Iterator[FloatArray]:  # random restarts drawn only when needed
        yield from (prev, model.work, model.home)
        rng = np.random.default_rng(k)
        for _ in range(_RESTARTS):
            yield rng.uniform(model.limits[:, 0], model.limits[:, 1])

    for seed in seeds():
        q = dls(model, target, seed)
        if q is not None:
            cands, dist = _closest(model, q[None], prev)
            return cands[0] if np.isfinite(dist[0]) else q
    log.debug("damped least squares found no solution for point %d", k)
    raise _unreachable(model, target[None], 0, False, index=k)
