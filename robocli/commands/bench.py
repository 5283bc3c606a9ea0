"""``robocli bench rtt|jitter|sip``: latency and timing statistics, against the built-in
simulators unless ``--url`` names a real robot."""

from __future__ import annotations

from typing import Any, Optional

import typer

from robocli.commands._common import pioneer_url, print_json, sigterm_as_interrupt

TARGETS = ("pioneer",)
TargetOpt = typer.Option("pioneer", "--target", "-t", help="Robot type: pioneer.")
UrlOpt = typer.Option(None, "--url", help="A real robot's URL (default: embedded simulator).")
JsonOpt = typer.Option(False, "--json", help="Machine-readable output.")


def _check_target(target: str) -> None:
    if target not in TARGETS:
        raise typer.BadParameter(f"unknown target {target!r}; choose from {', '.join(TARGETS)}")


def rtt(
    target: str = TargetOpt,
    url: Optional[str] = UrlOpt,  # noqa: UP007
    n: int = typer.Option(1000, "--n", "-n", min=10, max=1_000_000, help="Round trips."),
    json_out: bool = JsonOpt,
) -> None:
    """Request/acknowledge round trips through the real client, and the C floor."""
    from robocli import benchmarks as b

    _check_target(target)
    with sigterm_as_interrupt():
        floor = b.c_floor(n)
        with pioneer_url(url or "sim") as where:
            samples = b.pioneer_rtt(where, n)
    floor_stats = b.Stats.of(floor)
    results = [b.report("C floor (loopback TCP ping-pong)", floor),
               b.report(f"{target} CONFIG round trip", samples, floor_stats)]
    _show(results, {"client": samples}, json_out)


def jitter(
    target: str = TargetOpt,
    url: Optional[str] = UrlOpt,  # noqa: UP007
    n: int = typer.Option(300, "--n", "-n", min=10, help="SIP periods."),
    json_out: bool = JsonOpt,
) -> None:
    """SIP period statistics (the robot's 100 ms cycle as the client sees it)."""
    from robocli import benchmarks as b

    _check_target(target)
    with sigterm_as_interrupt(), pioneer_url(url or "sim") as where:
        timing = b.pioneer_sip_timing(where, n)
    _show([b.report("SIP period", timing["period"])], {"period": timing["period"]}, json_out,
          unit=1e-3, label="ms")


def sip(
    target: str = TargetOpt,
    url: Optional[str] = UrlOpt,  # noqa: UP007
    n: int = typer.Option(300, "--n", "-n", min=10, help="SIPs to collect."),
    json_out: bool = JsonOpt,
) -> None:
    """Client work per SIP and the keep-alive period (the MATLAB interface's histograms)."""
    from robocli import benchmarks as b

    _check_target(target)
    with sigterm_as_interrupt(), pioneer_url(url or "sim") as where:
        timing = b.pioneer_sip_timing(where, n)
    results = [b.report("client work per SIP", timing["work"])]
    if timing["keepalive"].size > 1:
        results.append(b.report("keep-alive period", timing["keepalive"]))
    _show(results, {"work": timing["work"]}, json_out)


def _show(results: list[dict[str, Any]], hist: dict[str, Any], json_out: bool,
          unit: float = 1e-6, label: str = "us") -> None:
    from robocli import benchmarks as b

    if json_out:
        print_json(results)
        return
    from rich.console import Console
    from rich.table import Table

    table = Table(title="all times in microseconds")
    for col in ("measurement", "n", "mean", "median", "std", "min", "max", "p90", "p99",
                "x floor (median, p99)"):
        table.add_column(col, justify="left" if col == "measurement" else "right")
    for r in results:
        ratio = (f"{r['x_floor_median']:.1f} / {r['x_floor_p99']:.1f}"
                 if "x_floor_median" in r else "")
        table.add_row(r["name"], str(r["n"]), *(f"{r[k]:.1f}" for k in
                      ("mean", "median", "std", "min", "max", "p90", "p99")), ratio)
    console = Console()
    console.print(table)
    for name, samples in hist.items():
        console.print(f"histogram: {name}")
        for line in b.histogram(samples, unit=unit, label=label):
            console.print(line, highlight=False)
