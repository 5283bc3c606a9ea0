"""Bench reports as ``robocli bench`` prints them, for a script or a notebook too: a table
of :class:`~robocli.bench.reports.Report` rows (each in its own unit) and histograms
(:func:`results_lines`), the hub's round trip (:func:`hub_rtt_lines`) and the hub
throughput run (:func:`throughput_lines`). Nothing here prints."""

from __future__ import annotations

import os
from typing import Any

__all__ = ["hub_rtt_lines", "results_lines", "throughput_lines", "unit_of"]


def unit_of(median_us: float) -> tuple[float, str]:
    """The display unit of a measurement: (its size in seconds, label); ms from 10 ms up,
    so that a 100 ms period reads ``100.0 ms``, not ``100013.6`` us."""
    return (1e-3, "ms") if median_us >= 10_000 else (1e-6, "us")


def results_lines(results: list[dict[str, Any]], hist: dict[str, Any],
                  floor_note: str = "") -> list[str]:  # fmt: skip
    """A table of ``results`` (each row in its own unit, named in the unit column) with
    their notes, then a histogram of each of ``hist``'s samples (s) in their unit."""
    import numpy as np

    from robocli.bench import stats as bs

    keys = ("mean", "median", "std", "min", "max", "p90", "p99")
    width = max([28, *(len(r["name"]) + 1 for r in results)])
    out = [f"{'measurement':<{width}}{'unit':>5}{'n':>7}" + "".join(f"{k:>9}" for k in keys)]
    for r in results:
        unit, label = unit_of(r["median"])
        values = "".join(f"{r[k] * 1e-6 / unit:>9.1f}" for k in keys)
        out.append(f"{r['name']:<{width}}{label:>5}{r['n']:>7}" + values)
        notes = [r["where"]] if "where" in r else []
        if "x_floor_median" in r:
            notes.append(f"= {r['x_floor_median']:.1f} x floor (median), "
                         f"{r['x_floor_p99']:.1f} x (p99)")  # fmt: skip
        if "target_met" in r:
            notes.append(f"target <= {r['target_median_x']:g} x / {r['target_p99_x']:g} x: "
                         + ("met" if r["target_met"] else "NOT met"))  # fmt: skip
        if notes:
            out.append("  " + "; ".join(notes))
    if floor_note:
        out.append(floor_note)
    for name, samples in hist.items():
        unit, label = unit_of(float(np.median(samples)) * 1e6)
        out.append(f"histogram: {name} ({label})")
        out += bs.histogram(samples, unit=unit, label=label)
    return out


def hub_rtt_lines(result: dict[str, Any]) -> list[str]:
    """``bench rtt --target hub``: its one row, in microseconds."""
    keys = ("mean", "median", "p90", "p99", "max")
    return [f"{'measurement (us)':<22}{'n':>7}" + "".join(f"{k:>9}" for k in keys),
            f"{result['name']:<22}{result['n']:>7}" + "".join(f"{result[k]:>9.1f}" for k in keys),
            f"  {result['where']}"]  # fmt: skip


def throughput_lines(r: dict[str, Any]) -> list[str]:
    """``bench throughput``'s report (:func:`robocli.bench.runs.hub_throughput`) as text."""
    out = [f"{r['clients']} clients in {r['workers']} processes x {', '.join(r['sensors'])}, "
           f"pulling each at {r['pull_hz']:g} Hz for {r['seconds']:g} s"]  # fmt: skip
    if r["not_served"]:
        out.append(f"  not served by this hub: {', '.join(r['not_served'])}")
    out.append(f"  pulls/s {r['pulls_per_s']:.0f}   samples/s {r['samples_per_s']:.0f}   MB/s "
               f"{r['bytes_per_s'] / 1e6:.1f}   gaps in sample times {r['lost_samples']}")
    if "pull_p99_ms" in r:
        out.append(f"  pull latency ms: median {r['pull_p50_ms']:.2f}  p99 {r['pull_p99_ms']:.2f}  "
                   f"max {r['pull_max_ms']:.2f}")  # fmt: skip
    if "hub_pull_p99_ms" in r:
        out.append(f"  of which in the hub (request framed to reply built): median "
                   f"{r['hub_pull_p50_ms']:.2f}  p99 {r['hub_pull_p99_ms']:.2f}")  # fmt: skip
    if "hub_cpu_cores" in r:
        out.append(f"  hub: {r['hub_cpu_cores']:.2f} cores, peak memory {r['hub_peak_rss_mb']:.0f} "
                   f"MB; clients: {r['client_cpu_cores']:.2f} cores (whole run, {os.cpu_count()} "
                   "CPUs here)")  # fmt: skip
        out.append(f"  samples the hub dropped for full buffers: {r.get('hub_dropped', '?')} "
                   "(before samples the clients pulled: their gaps)")  # fmt: skip
    for s, p in r["per_sensor"].items():
        out.append(f"  {s:<8} pulls {p['pulls']:>7}  samples {p['samples']:>8}  "
                   f"MB {p['bytes'] / 1e6:>8.1f}  lost {p['lost']}")  # fmt: skip
    out += [f"  error: {e}" for e in sorted(set(r["errors"]))[:5]]
    out.append("  target (p99 <= 5 ms, no loss, hub <= 1 core): "
               + ("met" if r["targets_met"] else "NOT met"))  # fmt: skip
    return out
