"""``robocli bench rtt|jitter|sip``: latency and timing statistics, against the built-in
simulators unless a URL names a real device.

Every bench stops within about a second on Ctrl-C (or SIGTERM), prints what it collected
so far and exits 130. On a terminal, runs longer than about 2 s show a progress bar on
stderr (stdout stays clean for ``--json``).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, Literal

import typer

from robocli.commands._common import (
    print_json,
    sigterm_as_interrupt,
)
from robocli.commands._options import count_option, json_option

if TYPE_CHECKING:
    pass

TARGETS = ("pioneer",)
TargetOpt = typer.Option("pioneer", "--target", "-t", help="What to measure: pioneer, arm or hub.")
JitterTargetOpt = typer.Option(
    "pioneer", "--target", "-t", help="What to measure: pioneer, arm or laser."
)
SipTargetOpt = typer.Option("pioneer", "--target", "-t", help="What to measure: pioneer.")
UrlOpt = typer.Argument(None, metavar="URL", show_default=False,
                        help="A real device's URL (default: a built-in simulator).")  # fmt: skip
JsonOpt = json_option()
OrderOpt = typer.Option(
    None, "--byte-order", help="arm: little (ABB, the default) or big (Fanuc, FS100)."
)
RealOpt = typer.Option(None, "--real-size", help="arm: bytes per real, 4 (default) or 8 (FLOAT64).")
ByteOrder = Literal["little", "big"]
RealSize = Literal[4, 8]
EXIT_INTERRUPTED = 130
#: A run shows progress once it has lasted this long (seconds), on a terminal only.
PROGRESS_AFTER = 2.0


def _check_target(target: str, also: tuple[str, ...] = ()) -> None:
    """``also``: the other targets this command measures (handled before this check)."""
    if target not in TARGETS:
        known = ", ".join((*TARGETS, *also))
        raise typer.BadParameter(f"unknown target {target!r}; choose from {known}")


def _check_paper_model(target: str, paper: bool) -> None:
    if paper and target != "arm":  # it models the ABB controller only
        raise typer.BadParameter(f"--paper-model is for --target arm, not {target!r}")


def _arm_wire(target: str, byte_order: str | None, real_size: int | None) -> tuple[str, int]:
    """``--byte-order`` and ``--real-size``: the Simple Message variant of an arm target
    (and of the simulator the bench starts); refused for the other targets."""
    from robocli.commands._arm import check_wire

    given = [name for name, value in (("--byte-order", byte_order), ("--real-size", real_size))
             if value is not None]  # fmt: skip
    if given and target != "arm":
        raise typer.BadParameter(f"{given[0]} is for --target arm, not {target!r}")
    wire = (byte_order or "little", real_size or 4)
    check_wire(*wire)
    return wire


class _Progress:
    """Rich progress on stderr, started only when stderr is a terminal and a stage has run
    for :data:`PROGRESS_AFTER` seconds (short runs stay silent; pipes never see it)."""

    def __init__(self) -> None:
        self.enabled = sys.stderr.isatty()
        self._bar: Any = None
        self._task: Any = None

    @contextmanager
    def stage(self, label: str, total: int) -> Iterator[Callable[[int], None]]:
        start = time.monotonic()

        def update(done: int) -> None:
            if not self.enabled:
                return
            if self._bar is None:
                if time.monotonic() - start < PROGRESS_AFTER:
                    return
                from rich.console import Console
                from rich.progress import Progress

                self._bar = Progress(console=Console(stderr=True), transient=True)
                self._bar.start()
                self._task = self._bar.add_task(label, total=total)
            self._bar.update(self._task, completed=done)

        try:
            yield update
        finally:
            if self._bar is not None:
                self._bar.stop()
                self._bar = None


def rtt(
    target: Literal["pioneer", "arm", "hub"] = TargetOpt,
    url: str | None = UrlOpt,
    n: int = count_option(1000, "Round trips.", min=10, max=1_000_000),
    floor_n: int | None = typer.Option(
        None, "--floor-n", min=10, max=1_000_000, help="Round trips of each C floor (default: n)."
    ),
    cpu: int | None = typer.Option(
        None, "--cpu", min=0, help="CPU for the same-CPU floor and the client (default: first)."
    ),
    json_out: bool = JsonOpt,
    paper: bool = typer.Option(False, "--paper-model", help="arm: paper-like simulator model."),
    byte_order: ByteOrder | None = OrderOpt,
    real_size: RealSize | None = RealOpt,
) -> None:
    """Request/acknowledge round trips through the real client, as multiples of the C
    ping-pong floor with both ends on one CPU (the floor across two CPUs is shown too).

    Without a URL: a bare Python socket, then the client, against a minimal C ARCOS
    responder (the client's own cost), then the client against the built-in simulator
    running in its own process; all pinned to one CPU.
    """
    from robocli.bench import runs
    from robocli.bench import stats as bs

    _check_paper_model(target, paper)
    wire = _arm_wire(target, byte_order, real_size)
    if target == "hub":  # the sensor hub's bench lives with its commands
        from robocli.commands.hub import bench_rtt

        return bench_rtt(url, n, json_out)
    if target == "arm":  # JOINT_TRAJ_PT round trips (Table 5)
        return _arm_bench("rtt", url, n, json_out, paper, floor_n, cpu, wire)
    _check_target(target, also=("arm", "hub"))
    with sigterm_as_interrupt():
        out = runs.pioneer_rtt(url, n, floor_n, cpu, stage=_Progress().stage)
    floor_run = out.runs[0][0]
    floor = bs.SampleStats.of(floor_run.values) if floor_run.count else None
    results = [
        bs.report(run.name, run.values, floor if i else None, targets, run.where)
        for i, (run, targets) in enumerate(out.runs)
        if run.count
    ]
    hist = {run.name: run.values for run, _ in out.runs if run.count and "floor" not in run.name}
    _show(results, hist, json_out, floor_note="x floor = multiple of the same-CPU C floor median")
    _finish(out.interrupted, out.samples)


def _laser_jitter(url: str | None, n: int, json_out: bool) -> None:
    """``bench jitter --target laser``: streamed scans of a laser (default: the embedded
    UTM-30LX simulator, 25 ms)."""
    from robocli.bench import runs
    from robocli.bench import stats as bs

    with sigterm_as_interrupt():
        timing, interrupted = runs.laser_timing(url, n, stage=_Progress().stage)
    names = {"period": "scan period (received)", "stamp_period": "scan period (stamped)",
             "delay": "stamp to reception", "decode": "decode one frame"}  # fmt: skip
    results = [bs.report(names[k], v) for k, v in timing.items() if v.size]
    if results:
        _show(results, {"period": timing["period"]} if timing["period"].size else {}, json_out)
    _finish(interrupted)


def _sip_timing(url: str | None, n: int) -> tuple[dict[str, Any], bool]:
    from robocli.bench import runs

    with sigterm_as_interrupt():
        return runs.sip_timing(url, n, stage=_Progress().stage)


def _finish(interrupted: bool, samples: int | None = None) -> None:
    if interrupted:
        typer.echo("interrupted: partial results" + (f" ({samples} samples)" if samples else ""),
                   err=True)  # fmt: skip
        raise typer.Exit(EXIT_INTERRUPTED)


def jitter(
    target: Literal["pioneer", "arm", "laser"] = JitterTargetOpt,
    url: str | None = UrlOpt,
    n: int = count_option(300, "SIP periods.", min=10),
    json_out: bool = JsonOpt,
    paper: bool = typer.Option(False, "--paper-model", help="arm: paper-like simulator model."),
    byte_order: ByteOrder | None = OrderOpt,
    real_size: RealSize | None = RealOpt,
) -> None:
    """SIP period statistics (the robot's 100 ms cycle as the client sees it); laser: the
    scan period as received and as stamped, the stamp-to-reception delay, the decode time."""
    from robocli.bench import stats as bs

    _check_paper_model(target, paper)
    if target == "laser":
        return _laser_jitter(url, n, json_out)
    wire = _arm_wire(target, byte_order, real_size)
    if target == "arm":  # the state period (Table 5)
        return _arm_bench("jitter", url, n, json_out, paper, wire=wire)
    _check_target(target, also=("arm",))
    timing, interrupted = _sip_timing(url, n)
    period = timing.get("period")
    if period is not None and period.size:
        _show([bs.report("SIP period", period)], {"period": period}, json_out)
    _finish(interrupted)


def sip(
    target: Literal["pioneer"] = SipTargetOpt,
    url: str | None = UrlOpt,
    n: int = count_option(300, "SIPs to collect.", min=10),
    json_out: bool = JsonOpt,
) -> None:
    """Client work per SIP and the keep-alive period (the MATLAB interface's histograms)."""
    from robocli.bench import stats as bs

    _check_target(target)
    timing, interrupted = _sip_timing(url, n)
    results = []
    work = timing.get("work")
    if work is not None and work.size:
        results.append(bs.report("client CPU per SIP", work))
    keep = timing.get("keepalive")
    if keep is not None and keep.size > 1:
        results.append(bs.report("keep-alive period", keep))
    if results:
        _show(results, {"work": work} if work is not None and work.size else {}, json_out)
    _finish(interrupted)


def _unit(median_us: float) -> tuple[float, str]:
    """The display unit of a measurement: (its size in seconds, label); ms from 10 ms up,
    so that a 100 ms period reads ``100.0 ms``, not ``100013.6`` us."""
    return (1e-3, "ms") if median_us >= 10_000 else (1e-6, "us")


def _show(
    results: list[dict[str, Any]],
    hist: dict[str, Any],
    json_out: bool,
    floor_note: str = "",
) -> None:
    """A table (each row in its own unit, named in the unit column) and histograms of
    ``hist`` in the unit of their samples; or JSON (microseconds, to the nanosecond).
    A reader that leaves early (``| head -1``) ends the output quietly, exit 0."""
    from robocli.commands._common import reader_may_leave

    with reader_may_leave():
        _print_results(results, hist, json_out, floor_note)


def _print_results(
    results: list[dict[str, Any]], hist: dict[str, Any], json_out: bool, floor_note: str
) -> None:
    import numpy as np

    from robocli.bench import stats as bs
    from robocli.commands._common import rounded

    if json_out:
        print_json(rounded(results, 3, {}))
        return
    keys = ("mean", "median", "std", "min", "max", "p90", "p99")
    width = max([28, *(len(r["name"]) + 1 for r in results)])
    typer.echo(f"{'measurement':<{width}}{'unit':>5}{'n':>7}" + "".join(f"{k:>9}" for k in keys))
    for r in results:
        unit, label = _unit(r["median"])
        values = "".join(f"{r[k] * 1e-6 / unit:>9.1f}" for k in keys)
        typer.echo(f"{r['name']:<{width}}{label:>5}{r['n']:>7}" + values)
        notes = [r["where"]] if "where" in r else []
        if "x_floor_median" in r:
            notes.append(
                f"= {r['x_floor_median']:.1f} x floor (median), {r['x_floor_p99']:.1f} x (p99)"
            )
        if "target_met" in r:
            notes.append(
                f"target <= {r['target_median_x']:g} x / {r['target_p99_x']:g} x: "
                + ("met" if r["target_met"] else "NOT met")
            )
        if notes:
            typer.echo("  " + "; ".join(notes))
    if floor_note:
        typer.echo(floor_note)
    for name, samples in hist.items():
        unit, label = _unit(float(np.median(samples)) * 1e6)
        typer.echo(f"histogram: {name} ({label})")
        for line in bs.histogram(samples, unit=unit, label=label):
            typer.echo(line)


def _arm_bench(kind: str, url: str | None, n: int, json_out: bool, paper: bool = False,
          floor_n: int | None = None, cpu: int | None = None,
          wire: tuple[str, int] = ("little", 4)) -> None:  # fmt: skip
    """``robocli bench rtt|jitter --target arm``: JOINT_TRAJ_PT round trips (after the C
    floor, as the Pioneer bench) or the state period, against ``url`` or the built-in ABB
    simulator in its own process (``paper``: its paper-like model), beside Table 5.
    ``wire``: (byte order, real size) of the controller, and of that simulator."""
    from robocli.bench import arm as ab
    from robocli.bench import runs as bench_runs
    from robocli.bench import stats as bs

    with sigterm_as_interrupt():
        out = bench_runs.arm_bench(kind, url, n, paper, floor_n, cpu, wire, _Progress().stage)
    runs, interrupted = [run for run, _ in out.runs], out.interrupted
    name = "JOINT_TRAJ_PT -> reply" if kind == "rtt" else "state period"
    floor = bs.SampleStats.of(runs[0].values) if kind == "rtt" and runs[0].count else None
    results = [bs.report(r.name, r.values, floor if "floor" not in r.name else None,
                        where=r.where) for r in runs if r.count]  # fmt: skip
    paper_row = ab.PAPER_TABLE5["rtt" if kind == "rtt" else "state period"]
    if json_out:
        results.append({"name": f"paper Table 5: {name}", "unit": "us", "reference": True,
                        **{k: v * 1e3 for k, v in paper_row.items()}})  # fmt: skip
    hist = {name: runs[-1].values} if runs and runs[-1].count else {}
    _show(
        results,
        {} if json_out else hist,
        json_out,
        floor_note="x floor = multiple of the same-CPU C floor median" if floor else "",
    )
    if not json_out:
        typer.echo("paper's Table 5 (IRB120, ms): " +
                   "  ".join(f"{k} {v:g}" for k, v in paper_row.items()))  # fmt: skip
    _finish(interrupted, out.samples)
