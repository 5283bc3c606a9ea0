"""``robocli bench rtt|jitter|sip``: latency and timing statistics, against the built-in
simulators unless ``--url`` names a real robot."""

from __future__ import annotations

from typing import Any

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
    url: str | None = UrlOpt,  # noqa: UP007
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
    results = [
        b.report("C floor (loopback TCP ping-pong)", floor),
        b.report(f"{target} CONFIG round trip", samples, floor_stats),
    ]
    _show(results, {"client": samples}, json_out)


def jitter(
    target: str = TargetOpt,
    url: str | None = UrlOpt,  # noqa: UP007
    n: int = typer.Option(300, "--n", "-n", min=10, help="SIP periods."),
    json_out: bool = JsonOpt,
) -> None:
    """SIP period statistics (the robot's 100 ms cycle as the client sees it)."""
    from robocli import benchmarks as b

    _check_target(target)
    with sigterm_as_interrupt(), pioneer_url(url or "sim") as where:
        timing = b.pioneer_sip_timing(where, n)
    _show(
        [b.report("SIP period", timing["period"])],
        {"period": timing["period"]},
        json_out,
        unit=1e-3,
        label="ms",
    )


def sip(
    target: str = TargetOpt,
    url: str | None = UrlOpt,  # noqa: UP007
    n: int = typer.Option(300, "--n", "-n", min=10, help="SIPs to collect."),
    json_out: bool = JsonOpt,
) -> None:
    """Client work per SIP and the keep-alive period (the MATLAB interface's histograms)."""
    from robocli import benchmarks as b

    _check_target(target)
    with sigterm_as_interrupt(), pioneer_url(url or "sim") as where:
        timing = b.pioneer_sip_timing(where, n)
    results = [b.report("client CPU per SIP", timing["work"])]
    if timing["keepalive"].size > 1:
        results.append(b.report("keep-alive period", timing["keepalive"]))
    _show(results, {"work": timing["work"]}, json_out)


def _show(
    results: list[dict[str, Any]],
    hist: dict[str, Any],
    json_out: bool,
    unit: float = 1e-6,
    label: str = "us",
) -> None:
    from robocli import benchmarks as b

    if json_out:
        print_json(results)
        return
    typer.echo(
        f"{'measurement (us)':<34}{'n':>7}"
        + "".join(f"{k:>10}" for k in ("mean", "median", "std", "min", "max", "p90", "p99"))
    )
    for r in results:
        typer.echo(
            f"{r['name']:<34}{r['n']:>7}"
            + "".join(
                f"{r[k]:>10.1f}" for k in ("mean", "median", "std", "min", "max", "p90", "p99")
            )
        )
        if "x_floor_median" in r:
            typer.echo(
                f"{'':<34}{'':>7}  = {r['x_floor_median']:.1f} x floor (median), "
                f"{r['x_floor_p99']:.1f} x floor (p99)"
            )
    for name, samples in hist.items():
        typer.echo(f"histogram: {name}")
        for line in b.histogram(samples, unit=unit, label=label):
            typer.echo(line)
