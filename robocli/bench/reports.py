"""``robocli bench rtt|jitter|sip`` as one call each, for a script too: run the bench of a
target (a URL, else a built-in simulator) and get a :class:`Report`, the rows of
:func:`robocli.bench.stats.report` (microseconds) and the samples worth a histogram.

>>> from robocli.bench.reports import rtt                                # doctest: +SKIP
>>> for row in rtt("pioneer", n=200).results:
...     print(row["name"], row["median"])
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from robocli.bench import runs
from robocli.bench import stats as bs
from robocli.bench.runs import Outcome, Stage, no_progress
from robocli.errors import InvalidArgument

__all__ = ["FLOOR_NOTE", "Report", "jitter", "rtt", "sip"]

FLOOR_NOTE = "x floor = multiple of the same-CPU C floor median"
Wire = tuple[str, int]


@dataclass
class Report:
    """What a bench measured: ``results`` (one :func:`~robocli.bench.stats.report` row per
    measurement, in microseconds), ``hist`` (samples in seconds, by name, worth a
    histogram), whether Ctrl-C ``interrupted`` it and how many ``samples`` it holds,
    ``floor_note`` (what the ``x_floor`` columns mean, when there are any) and ``paper``
    (for an arm: the measurement's name and the paper's Table 5 row for it, in ms)."""

    results: list[dict[str, Any]] = field(default_factory=list)
    hist: dict[str, Any] = field(default_factory=dict)
    interrupted: bool = False
    samples: int | None = None
    floor_note: str = ""
    paper: tuple[str, dict[str, float]] | None = None


def rtt(target: str = "pioneer", url: str | None = None, n: int = 1000,
        floor_n: int | None = None, cpu: int | None = None, *, paper: bool = False,
        wire: Wire = ("little", 4), stage: Stage = no_progress) -> Report:  # fmt: skip
    """Round trips through the real client: a Pioneer's (after the C ping-pong floor, as
    multiples of it), an arm's JOINT_TRAJ_PT (after the floor, beside the paper's Table 5)
    or a hub's empty pull. ``paper``: the arm simulator's paper-like model; ``wire``: the
    arm's (byte order, real size); ``stage``: a progress context per stage."""
    if target == "arm":
        return _arm("rtt", url, n, paper, floor_n, cpu, wire, stage)
    if target == "hub":
        out = runs.hub_rtt(url, n)
        return Report([bs.report(r.name, r.values, where=r.where) for r, _ in out.runs if r.count],
                      interrupted=out.interrupted)  # fmt: skip
    _pioneer_only(target, "arm", "hub")
    out = runs.pioneer_rtt(url, n, floor_n, cpu, stage=stage)
    floor_run = out.runs[0][0]
    floor = bs.SampleStats.of(floor_run.values) if floor_run.count else None
    results = [bs.report(run.name, run.values, floor if i else None, targets, run.where)
               for i, (run, targets) in enumerate(out.runs) if run.count]  # fmt: skip
    hist = {run.name: run.values for run, _ in out.runs if run.count and "floor" not in run.name}
    return Report(results, hist, out.interrupted, out.samples, FLOOR_NOTE)


def jitter(target: str = "pioneer", url: str | None = None, n: int = 300, *,
           paper: bool = False, wire: Wire = ("little", 4),
           stage: Stage = no_progress) -> Report:  # fmt: skip
    """Period statistics: a Pioneer's SIP period, an arm's state period (beside Table 5),
    or a laser's scan period as received and as stamped, the stamp-to-reception delay and
    the decode time."""
    if target == "arm":
        return _arm("jitter", url, n, paper, wire=wire, stage=stage)
    if target == "laser":
        timing, interrupted = runs.laser_timing(url, n, stage=stage)
        names = {"period": "scan period (received)", "stamp_period": "scan period (stamped)",
                 "delay": "stamp to reception", "decode": "decode one frame"}  # fmt: skip
        period = timing["period"]
        return Report([bs.report(names[k], v) for k, v in timing.items() if v.size],
                      {"period": period} if period.size else {}, interrupted)  # fmt: skip
    _pioneer_only(target, "arm", "laser")
    timing, interrupted = runs.sip_timing(url, n, stage=stage)
    period = timing.get("period")
    if period is None or not period.size:
        return Report(interrupted=interrupted)
    return Report([bs.report("SIP period", period)], {"period": period}, interrupted)


def sip(url: str | None = None, n: int = 300, *, stage: Stage = no_progress) -> Report:
    """A Pioneer client's CPU time per SIP and its keep-alive period."""
    timing, interrupted = runs.sip_timing(url, n, stage=stage)
    results, hist = [], {}
    work = timing.get("work")
    if work is not None and work.size:
        results.append(bs.report("client CPU per SIP", work))
        hist["work"] = work
    keep = timing.get("keepalive")
    if keep is not None and keep.size > 1:
        results.append(bs.report("keep-alive period", keep))
    return Report(results, hist, interrupted)


def _pioneer_only(target: str, *also: str) -> None:
    if target != "pioneer":
        raise InvalidArgument(f"unknown target {target!r}; choose from pioneer, {', '.join(also)}")


def _arm(kind: str, url: str | None, n: int, paper: bool = False, floor_n: int | None = None,
         cpu: int | None = None, wire: Wire = ("little", 4),
         stage: Stage = no_progress) -> Report:  # fmt: skip
    from robocli.bench import arm as ab

    out: Outcome = runs.arm_bench(kind, url, n, paper, floor_n, cpu, wire, stage)
    measured = [run for run, _ in out.runs]
    name = "JOINT_TRAJ_PT -> reply" if kind == "rtt" else "state period"
    floor = bs.SampleStats.of(measured[0].values) if kind == "rtt" and measured[0].count else None
    results = [bs.report(r.name, r.values, floor if "floor" not in r.name else None,
                         where=r.where) for r in measured if r.count]  # fmt: skip
    hist = {name: measured[-1].values} if measured and measured[-1].count else {}
    return Report(results, hist, out.interrupted, out.samples, FLOOR_NOTE if floor else "",
                  (name, ab.PAPER_TABLE5["rtt" if kind == "rtt" else "state period"]))  # fmt: skip
