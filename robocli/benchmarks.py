"""Latency, jitter and per-packet cost, measured through the real client code paths.

Statistics follow the IRB120 paper's Table 5 (n, mean, median, std, min, max) plus p90/p99,
and every latency is also given as a multiple of the machine's floor: a C ping-pong over
loopback TCP measured in the same run (:func:`robocli.core.pingpong_floor`), so figures mean
the same on any machine. All samples are in seconds.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import numpy.typing as npt


@dataclass(frozen=True)
class Stats:
    n: int
    mean: float
    median: float
    std: float
    min: float
    max: float
    p90: float
    p99: float

    @classmethod
    def of(cls, samples: npt.ArrayLike) -> Stats:
        a = np.asarray(samples, dtype=np.float64)
        if a.size == 0:
            raise ValueError("no samples")
        p50, p90, p99 = np.percentile(a, [50, 90, 99])
        return cls(
            n=int(a.size),
            mean=float(a.mean()),
            median=float(p50),
            std=float(a.std(ddof=1)) if a.size > 1 else 0.0,
            min=float(a.min()),
            max=float(a.max()),
            p90=float(p90),
            p99=float(p99),
        )

    def as_dict(self, scale: float = 1.0) -> dict[str, float]:
        """Fields as a dict, values multiplied by ``scale`` (``n`` untouched)."""
        return {k: (v if k == "n" else v * scale) for k, v in asdict(self).items()}


def histogram(
    samples: npt.ArrayLike, bins: int = 12, width: int = 40, unit: float = 1e-6, label: str = "us"
) -> list[str]:
    """A text histogram: one line per bin, ``[lo, hi) count bar``."""
    a = np.asarray(samples, dtype=np.float64) / unit
    if a.size == 0:
        return []
    lo, hi = float(a.min()), float(a.max())
    if hi == lo:
        hi = lo + 1.0
    counts, edges = np.histogram(a, bins=bins, range=(lo, hi))
    top = max(int(counts.max()), 1)
    return [
        f"{edges[i]:10.1f} - {edges[i + 1]:10.1f} {label} {int(c):7d} "
        + "#" * max(int(c) and 1, round(width * int(c) / top))
        for i, c in enumerate(counts)
    ]


def c_floor(n: int = 1000, msg_size: int = 16) -> npt.NDArray[np.float64]:
    """Round trips of two C threads over loopback TCP: the machine's floor."""
    from robocli.core import pingpong_floor

    return pingpong_floor(n, msg_size)


def pioneer_rtt(url: str, n: int = 1000, warmup: int = 20) -> npt.NDArray[np.float64]:
    """CONFIG request -> CONFIG reply round trips through :class:`Pioneer` (its reader thread
    included), ``n`` samples after ``warmup`` unrecorded ones."""
    from robocli.devices.pioneer import Pioneer

    out = np.empty(n, dtype=np.float64)
    with Pioneer.connect(url) as robot:
        for i in range(-warmup, n):
            start = time.perf_counter()
            robot.request_config(timeout=2.0)
            if i >= 0:
                out[i] = time.perf_counter() - start
    return out


def pioneer_sip_timing(url: str, n: int = 300) -> dict[str, npt.NDArray[np.float64]]:
    """Collect ``n`` SIPs: their periods, the client work per SIP and keep-alive periods."""
    from robocli.devices.pioneer import Pioneer

    with Pioneer.connect(url) as robot:
        first = robot.stats.sips
        while robot.stats.sips - first < n + 1:
            robot.wait_for_sip(timeout=robot.sip_timeout)
        sip_times = np.array(robot.stats.sip_times, dtype=np.float64)[-(n + 1) :]
        work = np.array(robot.stats.sip_work, dtype=np.float64)[-n:]
        keep = np.diff(np.array(robot.stats.keepalive_times, dtype=np.float64))
    return {"period": np.diff(sip_times), "work": work, "keepalive": keep}


def report(name: str, samples: npt.ArrayLike, floor: Stats | None = None) -> dict[str, Any]:
    """JSON-ready summary of one measurement, in microseconds, with floor multiples."""
    stats = Stats.of(samples)
    out: dict[str, Any] = {"name": name, "unit": "us", **stats.as_dict(1e6)}
    if floor is not None and floor.median > 0:
        out["x_floor_median"] = stats.median / floor.median
        out["x_floor_p99"] = stats.p99 / floor.median
    return out
