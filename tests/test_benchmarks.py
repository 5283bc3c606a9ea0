"""Statistics of `robocli bench` on inputs with known answers (no wall-clock asserts)."""

from __future__ import annotations

import numpy as np
import pytest

from robocli.benchmarks import Stats, histogram, report


def test_stats_of_known_samples() -> None:
    s = Stats.of([1.0, 2.0, 3.0, 4.0, 5.0])
    assert (s.n, s.mean, s.median, s.min, s.max) == (5, 3.0, 3.0, 1.0, 5.0)
    assert s.std == pytest.approx(np.sqrt(2.5))  # sample standard deviation
    assert s.p90 == pytest.approx(4.6) and s.p99 == pytest.approx(4.96)


def test_stats_single_sample_and_empty() -> None:
    assert Stats.of([7.0]).std == 0.0
    with pytest.raises(ValueError):
        Stats.of([])


def test_report_scales_to_microseconds_and_floor_multiples() -> None:
    floor = Stats.of([10e-6] * 3)
    r = report("x", [20e-6, 40e-6, 60e-6], floor)
    assert r["median"] == pytest.approx(40.0) and r["n"] == 3
    assert r["x_floor_median"] == pytest.approx(4.0)


def test_histogram_counts_every_sample() -> None:
    samples = np.array([1, 1, 2, 3, 3, 3, 10], dtype=float) * 1e-6
    lines = histogram(samples, bins=3)
    assert len(lines) == 3
    assert sum(int(line.split()[4]) for line in lines) == 7
    assert histogram([]) == []
    assert len(histogram([5e-6, 5e-6], bins=2)) == 2  # all equal: still a valid range
