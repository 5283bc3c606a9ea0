"""Simulated-vs-measured comparison: automatic time alignment, then per-joint RMSE and MAE
(rad) and TCP position error (mm), as in the IRB120 paper's Table 4 but without hand-picked
reference points.

Alignment works on a common uniform grid: motion onset in each log bounds the search, the
cross-correlation of joint velocities (summed over joints) picks the lag, and the least
squared position difference around it refines the lag to a fraction of a sample.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from robocli.kinematics.errors import ValidationError
from robocli.kinematics.fk import fk_positions
from robocli.kinematics.model import FloatArray, RobotModel
from robocli.kinematics.trajlog import TrajectoryLog

MAX_GRID = 2_000_000
_REFINE = 3


@dataclass(frozen=True)
class Validation:
    """Result of :func:`validate`. ``delay_s``: the measured clock reads ``sim time +
    delay_s`` at the same motion (how late the measured motion came when both logs count
    from their start, as generated and recorded logs do). ``start_delay_s``: the same,
    each log's time counted from its first sample (meaningful whatever clocks the logs are
    on). Errors are measured minus simulated."""

    delay_s: float
    onset_delay_s: float | None
    samples: int
    rmse: FloatArray
    mae: FloatArray
    max_abs: FloatArray
    tcp_rmse_mm: float | None
    tcp_mean_mm: float | None
    tcp_max_mm: float | None
    start_delay_s: float = math.nan

    def to_dict(self) -> dict[str, Any]:
        """Plain numbers for JSON output."""
        return {
            "delay_s": self.delay_s,
            "start_delay_s": self.start_delay_s,
            "onset_delay_s": self.onset_delay_s,
            "samples": self.samples,
            "joints": [
                {
                    "joint": j + 1,
                    "rmse_rad": float(self.rmse[j]),
                    "mae_rad": float(self.mae[j]),
                    "max_abs_rad": float(self.max_abs[j]),
                }
                for j in range(self.rmse.shape[0])
            ],
            "max_rmse_rad": float(np.max(self.rmse)),
            "max_mae_rad": float(np.max(self.mae)),
            "tcp_rmse_mm": self.tcp_rmse_mm,
            "tcp_mean_mm": self.tcp_mean_mm,
            "tcp_max_mm": self.tcp_max_mm,
        }


def _grid_step(sim: TrajectoryLog, meas: TrajectoryLog) -> float:
    steps = [float(np.median(np.diff(x.time))) for x in (sim, meas) if len(x) > 1]
    if not steps:
        raise ValidationError("each log needs at least two samples")
    dt = min(steps)
    span = max(float(sim.time[-1] - sim.time[0]), float(meas.time[-1] - meas.time[0]))
    return max(dt, span / MAX_GRID)


def _resample(log: TrajectoryLog, dt: float) -> FloatArray:
    n = int(math.floor((log.time[-1] - log.time[0]) / dt + 1e-9)) + 1
    grid = log.time[0] + dt * np.arange(n)
    return np.stack(
        [np.interp(grid, log.time, log.positions[:, j]) for j in range(log.n_joints)], axis=1
    )


def _onset(disp: FloatArray, threshold: float) -> int | None:
    moving = np.nonzero(disp > threshold)[0]
    return int(moving[0]) if moving.size else None


def _noise_level(x: FloatArray) -> float:
    """Robust white-noise estimate from second differences (motion is smooth, noise is not)."""
    if x.shape[0] < 4:
        return 0.0
    d2 = np.diff(x, n=2, axis=0)
    return float(np.median(np.abs(d2)) * 1.4826 / math.sqrt(6.0))


def align(sim: TrajectoryLog, meas: TrajectoryLog) -> tuple[float, float | None]:
    """Delay (s) of ``meas`` against ``sim``, and the onset-only estimate (``None`` when a
    log does not move)."""
    if sim.n_joints != meas.n_joints:
        raise ValidationError(
            f"the logs have {sim.n_joints} and {meas.n_joints} joints: compare the same robot"
        )
    dt = _grid_step(sim, meas)
    s = _resample(sim, dt)
    m = _resample(meas, dt)
    ds = np.linalg.norm(s - s[0], axis=1)
    dm = np.linalg.norm(m - m[0], axis=1)
    peak = max(float(ds.max()), float(dm.max()))
    noise = max(_noise_level(s), _noise_level(m))
    threshold = max(0.05 * peak, 6.0 * noise * math.sqrt(sim.n_joints))
    on_s, on_m = _onset(ds, threshold), _onset(dm, threshold)
    base = meas.time[0] - sim.time[0]
    onset_lag = None if on_s is None or on_m is None else on_m - on_s
    vs, vm = np.diff(s, axis=0), np.diff(m, axis=0)
    lags = np.arange(-(vs.shape[0] - 1), vm.shape[0])
    if vs.shape[0] and vm.shape[0]:
        size = 1 << int(math.ceil(math.log2(vs.shape[0] + vm.shape[0])))
        spec = np.fft.rfft(vm, size, axis=0) * np.conj(np.fft.rfft(vs, size, axis=0))
        corr = np.fft.irfft(spec.sum(axis=1), size)
        xc = np.concatenate([corr[size - (vs.shape[0] - 1) :], corr[: vm.shape[0]]])
    else:
        xc = np.zeros(lags.shape[0])
    allowed = np.ones(lags.shape[0], dtype=bool)
    if onset_lag is not None:
        window = max(10, s.shape[0] // 4)
        allowed = np.abs(lags - onset_lag) <= window
    lag = int(lags[np.argmax(np.where(allowed, xc, -np.inf))]) if peak > 0 else 0
    frac = _refine(s, m, lag)
    onset_s = None if onset_lag is None else float(base + onset_lag * dt)
    return float(base + frac * dt), onset_s


def _refine(s: FloatArray, m: FloatArray, lag: int) -> float:
    """Lag minimising the mean squared position difference near ``lag``, with a parabola
    through the best three for a fractional sample."""

    def cost(k: int) -> float:
        lo, hi = max(0, -k), min(s.shape[0], m.shape[0] - k)
        if hi - lo < 2:
            return math.inf
        diff = s[lo:hi] - m[lo + k : hi + k]
        return float(np.mean(diff * diff))

    cands = range(lag - _REFINE, lag + _REFINE + 1)
    costs = {k: cost(k) for k in cands}
    best = min(costs, key=lambda k: costs[k])
    c0, c1, c2 = costs.get(best - 1, math.inf), costs[best], costs.get(best + 1, math.inf)
    if not (math.isfinite(c0) and math.isfinite(c2)):
        return float(best)
    denom = c0 - 2 * c1 + c2
    return float(best + (0.5 * (c0 - c2) / denom if denom > 0 else 0.0))


def validate(
    sim: TrajectoryLog,
    meas: TrajectoryLog,
    model: RobotModel | None = None,
    delay_s: float | None = None,
) -> Validation:
    """Compare a measured run with its simulation after aligning them in time (or at a
    given ``delay_s``). TCP errors use the logs' TCP columns, else FK of ``model``."""
    onset = None
    for name, log in (("simulated", sim), ("measured", meas)):
        if len(log) < 2:
            raise ValidationError(f"the {name} log has {len(log)} sample; each log needs at "
                                  "least two")  # fmt: skip
    if delay_s is None:
        delay_s, onset = align(sim, meas)
    elif sim.n_joints != meas.n_joints:
        raise ValidationError(f"the logs have {sim.n_joints} and {meas.n_joints} joints")
    t = sim.time + delay_s
    inside = (t >= meas.time[0] - 1e-12) & (t <= meas.time[-1] + 1e-12)
    if int(inside.sum()) < 2:
        raise ValidationError("the logs do not overlap in time after alignment")
    t = np.clip(t[inside], meas.time[0], meas.time[-1])
    q_meas = np.stack(
        [np.interp(t, meas.time, meas.positions[:, j]) for j in range(meas.n_joints)], axis=1
    )
    err = q_meas - sim.positions[inside]
    tcp_sim = sim.tcp[inside] if sim.tcp is not None else None
    if meas.tcp is not None:
        tcp_meas: FloatArray | None = np.stack(
            [np.interp(t, meas.time, meas.tcp[:, j]) for j in range(3)], axis=1
        )
    elif model is not None:
        tcp_meas = fk_positions(model, q_meas)
    else:
        tcp_meas = None
    if tcp_sim is None and model is not None:
        tcp_sim = fk_positions(model, sim.positions[inside])
    tcp_stats: tuple[float | None, float | None, float | None] = (None, None, None)
    if tcp_sim is not None and tcp_meas is not None:
        dist = np.linalg.norm(tcp_meas - tcp_sim, axis=1) * 1e3
        tcp_stats = (float(np.sqrt(np.mean(dist**2))), float(np.mean(dist)), float(dist.max()))
    return Validation(
        delay_s=float(delay_s),
        onset_delay_s=onset,
        samples=int(err.shape[0]),
        start_delay_s=float(delay_s - (meas.time[0] - sim.time[0])),
        rmse=np.sqrt(np.mean(err**2, axis=0)),
        mae=np.mean(np.abs(err), axis=0),
        max_abs=np.max(np.abs(err), axis=0),
        tcp_rmse_mm=tcp_stats[0],
        tcp_mean_mm=tcp_stats[1],
        tcp_max_mm=tcp_stats[2],
    )


def shifted(
    log: TrajectoryLog, delay_s: float, pad_s: float = 0.0, noise_rad: float = 0.0, seed: int = 0
) -> TrajectoryLog:
    """A copy of ``log`` as a controller might record it: ``pad_s`` of standing still
    before and after, the clock shifted by ``delay_s``, Gaussian joint noise ``noise_rad``.
    For tests and demonstrations."""
    dt = float(np.median(np.diff(log.time))) if len(log) > 1 else 0.01
    n_pad = int(round(pad_s / dt))
    before = log.time[0] - dt * np.arange(n_pad, 0, -1)
    after = log.time[-1] + dt * np.arange(1, n_pad + 1)
    time = np.concatenate([before, log.time, after]) + delay_s
    q = np.concatenate(
        [
            np.repeat(log.positions[:1], n_pad, axis=0),
            log.positions,
            np.repeat(log.positions[-1:], n_pad, axis=0),
        ]
    )
    if noise_rad > 0:
        q = q + np.random.default_rng(seed).normal(0.0, noise_rad, q.shape)
    tcp = None
    if log.tcp is not None and noise_rad == 0:
        tcp = np.concatenate(
            [np.repeat(log.tcp[:1], n_pad, axis=0), log.tcp, np.repeat(log.tcp[-1:], n_pad, axis=0)]
        )
    return TrajectoryLog.from_positions(time, q, tcp)


def as_array(values: npt.ArrayLike) -> FloatArray:
    """Float array view (helper for callers building logs by hand)."""
    return np.asarray(values, dtype=float)
