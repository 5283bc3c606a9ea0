"""Statistics of a benchmark: Table 5 of the IRB120 paper (n, mean, median, std, min, max)
plus p90/p99, a :class:`Run` that collects samples as they come (so a run stopped by Ctrl-C
keeps what it collected), text histograms and JSON-ready reports with floor multiples. All
samples are in seconds.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

Progress = Callable[[int], None]


@dataclass(frozen=True)
class SampleStats:
    """Table-5 statistics of a sample set (seconds, or whatever unit the samples are in)."""

    n: int
    mean: float
    median: float
    std: float
    min: float
    max: float
    p90: float
    p99: float

    @classmethod
    def of(cls, samples: npt.ArrayLike) -> SampleStats:
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


@dataclass
class Run:
    """One measurement being collected: up to ``n`` samples, ``count`` of them taken so far.

    ``where`` says on which CPUs the ends ran (e.g. ``"client CPU 0, responder CPU 0"``).
    """

    name: str
    n: int
    where: str = ""
    samples: npt.NDArray[np.float64] = field(init=False, repr=False)
    count: int = 0

    def __post_init__(self) -> None:
        if self.n <= 0:
            raise ValueError("n must be positive")
        self.samples = np.empty(self.n, dtype=np.float64)

    @property
    def values(self) -> npt.NDArray[np.float64]:
        """The samples taken so far."""
        return self.samples[: self.count]

    @property
    def complete(self) -> bool:
        return self.count == self.n


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
    # enough decimals that neighbouring edges differ (a 0.02 ms spread: 99.91 - 99.93)
    digits = min(6, max(1, 1 - math.floor(math.log10((hi - lo) / bins))))
    return [
        f"{edges[i]:10.{digits}f} - {edges[i + 1]:10.{digits}f} {label} {int(c):7d} "
        + "#" * max(int(c) and 1, round(width * int(c) / top))
        for i, c in enumerate(counts)
    ]


def report(
    name: str,
    samples: npt.ArrayLike,
    floor: SampleStats | None = None,
    targets: tuple[float, float] | None = None,
    where: str = "",
) -> dict[str, Any]:
    """JSON-ready summary of one measurement, in microseconds, with floor multiples.

    ``targets``: (median, p99) limits as multiples of the floor's median; the summary then
    says whether each is met.
    """
    stats = SampleStats.of(samples)
    out: dict[str, Any] = {"name": name, "unit": "us", **stats.as_dict(1e6)}
    if where:
        out["where"] = where
    if floor is not None and floor.median > 0:
        out["x_floor_median"] = stats.median / floor.median
        out["x_floor_p99"] = stats.p99 / floor.median
        if targets is not None:
            out["target_median_x"], out["target_p99_x"] = targets
            out["target_met"] = bool(
                out["x_floor_median"] <= targets[0] and out["x_floor_p99"] <= targets[1]
            )
    return out
