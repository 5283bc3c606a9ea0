"""Forward kinematics and the geometric Jacobian, vectorised over many poses with NumPy.

Each joint updates a rotation kept as three column arrays and a position, all of shape
(N, 3): no per-pose Python loop and no N x 4 x 4 temporaries until the caller asks for them.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from robocli.kinematics.errors import KinematicsError
from robocli.kinematics.model import FloatArray, RobotModel

MAX_POSES = 50_000_000
CHUNK = 16_384  # poses per pass: the working set stays in cache


def _joints(model: RobotModel, q: npt.ArrayLike) -> FloatArray:
    arr = np.asarray(q, dtype=float)
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != model.n_joints:
        raise KinematicsError(
            f"{model.name}: joint arrays are N x {model.n_joints}, got shape {np.shape(q)}"
        )
    if arr.shape[0] > MAX_POSES:
        raise KinematicsError(f"at most {MAX_POSES} poses per call, got {arr.shape[0]}")
    return arr


def _chain(
    model: RobotModel, q: FloatArray, keep_frames: bool = False
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, list[tuple[FloatArray, FloatArray]]]:
    """Columns x, y, z of the flange rotation and its position, each (3, N); with
    ``keep_frames`` also the (z axis, origin) of frames 0..n-1, each (3, N)."""
    n = q.shape[0]
    theta = (q + model.offset).T  # n_joints x N, each row contiguous
    ct_all = np.cos(theta)
    st_all = np.sin(theta)
    zero = np.zeros(n)
    one = np.ones(n)
    x = np.stack([one, zero, zero])
    y = np.stack([zero, one, zero])
    z = np.stack([zero, zero, one])
    p = np.zeros((3, n))
    frames: list[tuple[FloatArray, FloatArray]] = []
    for i in range(model.n_joints):
        if keep_frames:
            frames.append((z.copy(), p.copy()))
        ct, st = ct_all[i], st_all[i]
        a, d = float(model.a[i]), float(model.d[i])
        ca, sa = float(np.cos(model.alpha[i])), float(np.sin(model.alpha[i]))
        # Rz(theta) Tz(d) Tx(a) Rx(alpha) applied on the right of the current frame
        if d != 0.0:
            p = p + d * z
        nx = x * ct
        nx += y * st
        ny = y * ct
        ny -= x * st
        if a != 0.0:
            p = p + a * nx
        x = nx
        if abs(ca) < 1e-15 and abs(abs(sa) - 1.0) < 1e-15:  # alpha = +-90 deg: a permutation
            y, z = (z, -ny) if sa > 0 else (-z, ny)
        elif sa == 0.0 and ca == 1.0:
            y = ny
        else:
            y, z = ny * ca + z * sa, z * ca - ny * sa
    return x, y, z, p, frames


def _chunks(n: int) -> list[slice]:
    return [slice(i, min(n, i + CHUNK)) for i in range(0, n, CHUNK)] or [slice(0, 0)]


def fk(model: RobotModel, q: npt.ArrayLike) -> FloatArray:
    """Flange poses of ``q`` (N x n rad, or one pose of n): homogeneous matrices N x 4 x 4."""
    arr = _joints(model, q)
    out = np.zeros((arr.shape[0], 4, 4))
    out[:, 3, 3] = 1.0
    for part in _chunks(arr.shape[0]):
        x, y, z, p, _ = _chain(model, arr[part])
        view = out[part]
        view[:, :3, 0] = x.T
        view[:, :3, 1] = y.T
        view[:, :3, 2] = z.T
        view[:, :3, 3] = p.T
    return out


def fk_positions(model: RobotModel, q: npt.ArrayLike) -> FloatArray:
    """Flange positions (m) of ``q`` (N x n rad, or one pose of n): N x 3."""
    arr = _joints(model, q)
    out = np.empty((arr.shape[0], 3))
    for part in _chunks(arr.shape[0]):
        out[part] = _chain(model, arr[part])[3].T
    return out


def jacobian(model: RobotModel, q: npt.ArrayLike) -> FloatArray:
    """Geometric Jacobian of one pose in the base frame: 6 x n, linear rows first.

    Column i is ``[z_i x (p - o_i); z_i]`` for the axis ``z_i`` and origin ``o_i`` of joint i.
    """
    arr = _joints(model, q)
    if arr.shape[0] != 1:
        raise KinematicsError("jacobian() takes one pose")
    _, _, _, p, frames = _chain(model, arr, keep_frames=True)
    zs = np.stack([f[0][:, 0] for f in frames], axis=1)  # 3 x n
    os_ = np.stack([f[1][:, 0] for f in frames], axis=1)
    lin = np.cross(zs.T, (p[:, 0][:, None] - os_).T).T
    return np.vstack([lin, zs])
