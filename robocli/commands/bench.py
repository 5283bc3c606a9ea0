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
from typing import Any, Literal

import typer

from robocli.commands._arm import ByteOrder, RealSize
from robocli.commands._common import print_json, sigterm_as_interrupt
from robocli.commands._options import count_option, json_option
from robocli.errors import EXIT_INTERRUPTED


def _target(what: str) -> Any:
    return typer.Option("pioneer", "--target", "-t", help=f"What to measure: {what}.")


UrlOpt = typer.Argument(None, metavar="URL", show_default=False,
                        help="A real device's URL (default: a built-in simulator).")  # fmt: skip
JsonOpt = json_option()
OrderOpt = typer.Option(None, "--byte-order", help="arm: little (ABB, the default) or big "
                        "(Fanuc, FS100).")  # fmt: skip
PaperOpt = typer.Option(False, "--paper-model", help="arm: paper-like simulator model.")
RealOpt = typer.Option(None, "--real-size", help="arm: bytes per real, 4 (default) or 8 (FLOAT64).")
#: A run shows progress once it has lasted this long (seconds), on a terminal only.
PROGRESS_AFTER = 2.0


def _check_paper_model(target: str, paper: bool) -> None:
    if paper and target != "arm":  # it models the ABB controller only
        raise typer.BadParameter(f"--paper-model is for --target arm, not {target!r}")


def _arm_wire(target: str, byte_order: str | None, real_size: int | None) -> tuple[str, int]:
    """``--byte-order`` and ``--real-size``: the Simple Message variant of an arm target
    (and of the simulator the bench starts); refused for the other targets."""
    given = [name for name, value in (("--byte-order", byte_order), ("--real-size", real_size))
             if value is not None]  # fmt: skip
    if given and target != "arm":
        raise typer.BadParameter(f"{given[0]} is for --target arm, not {target!r}")
    return byte_order or "little", real_size or 4


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
    target: Literal["pioneer", "arm", "hub"] = _target("pioneer, arm or hub"),
    url: str | None = UrlOpt,
    n: int = count_option(1000, "Round trips.", min=10, max=1_000_000),
    floor_n: int | None = typer.Option(None, "--floor-n", min=10, max=1_000_000, help="Round "
                                       "trips of each C floor (default: n)."),  # fmt: skip
    cpu: int | None = typer.Option(None, "--cpu", min=0, help="CPU for the same-CPU floor and the "
                                   "client (default: first)."),  # fmt: skip
    json_out: bool = JsonOpt,
    paper: bool = PaperOpt,
    byte_order: ByteOrder | None = OrderOpt,
    real_size: RealSize | None = RealOpt,
) -> None:
    """Request/acknowledge round trips through the real client, as multiples of the C
    ping-pong floor with both ends on one CPU (the floor across two CPUs is shown too).

    Without a URL: a bare Python socket, then the client, against a minimal C ARCOS
    responder (the client's own cost), then the client against the built-in simulator
    running in its own process; all pinned to one CPU.
    """
    from robocli.bench import reports

    _check_paper_model(target, paper)
    wire = _arm_wire(target, byte_order, real_size)
    with sigterm_as_interrupt():
        report = reports.rtt(target, url, n, floor_n, cpu, paper=paper, wire=wire,
                             stage=_Progress().stage)  # fmt: skip
    if target == "hub":
        _hub_table(report, json_out)
    else:
        _render(report, json_out)


def _render(report: Any, json_out: bool) -> None:
    """A report's table and histograms (or JSON), the paper's Table 5 row for an arm; exit
    130 when Ctrl-C ended the run."""
    results, hist, paper = list(report.results), report.hist, report.paper
    if paper is not None and json_out:
        results.append({"name": f"paper Table 5: {paper[0]}", "unit": "us", "reference": True,
                        **{k: v * 1e3 for k, v in paper[1].items()}})  # fmt: skip
    if results or report.floor_note or paper:  # rtt and arm: the table even when empty
        _show(results, {} if json_out and paper else hist, json_out, report.floor_note)
    if paper is not None and not json_out:
        typer.echo("paper's Table 5 (IRB120, ms): " +
                   "  ".join(f"{k} {v:g}" for k, v in paper[1].items()))  # fmt: skip
    _finish(report.interrupted, report.samples)


def _hub_table(report: Any, json_out: bool) -> None:
    """``bench rtt --target hub``: its one row, in microseconds."""
    from robocli.bench.text import hub_rtt_lines
    from robocli.commands._common import echo_lines

    for result in report.results:
        if json_out:
            print_json([result])
            continue
        echo_lines(hub_rtt_lines(result))
    if report.interrupted:
        raise typer.Exit(EXIT_INTERRUPTED)


def _finish(interrupted: bool, samples: int | None = None) -> None:
    if interrupted:
        typer.echo("interrupted: partial results" + (f" ({samples} samples)" if samples else ""),
                   err=True)  # fmt: skip
        raise typer.Exit(EXIT_INTERRUPTED)


def jitter(
    target: Literal["pioneer", "arm", "laser"] = _target("pioneer, arm or laser"),
    url: str | None = UrlOpt,
    n: int = count_option(300, "SIP periods.", min=10),
    json_out: bool = JsonOpt,
    paper: bool = PaperOpt,
    byte_order: ByteOrder | None = OrderOpt,
    real_size: RealSize | None = RealOpt,
) -> None:
    """SIP period statistics (the robot's 100 ms cycle as the client sees it); laser: the
    scan period as received and as stamped, the stamp-to-reception delay, the decode time."""
    from robocli.bench import reports

    _check_paper_model(target, paper)
    wire = _arm_wire(target, byte_order, real_size) if target != "laser" else ("little", 4)
    with sigterm_as_interrupt():
        report = reports.jitter(target, url, n, paper=paper, wire=wire, stage=_Progress().stage)
    _render(report, json_out)


def sip(
    target: Literal["pioneer"] = _target("pioneer"),
    url: str | None = UrlOpt,
    n: int = count_option(300, "SIPs to collect.", min=10),
    json_out: bool = JsonOpt,
) -> None:
    """Client work per SIP and the keep-alive period (the MATLAB interface's histograms)."""
    from robocli.bench import reports

    with sigterm_as_interrupt():
        _render(reports.sip(url, n, stage=_Progress().stage), json_out)


def _show(results: list[dict[str, Any]], hist: dict[str, Any], json_out: bool,
          floor_note: str = "") -> None:  # fmt: skip
    """A table (each row in its own unit, named in the unit column) and histograms of
    ``hist`` in the unit of their samples; or JSON (microseconds, to the nanosecond).
    A reader that leaves early (``| head -1``) ends the output quietly, exit 0."""
    from robocli.bench.text import results_lines
    from robocli.commands._common import echo_lines, reader_may_leave, rounded

    with reader_may_leave():
        if json_out:
            print_json(rounded(results, 3, {}))
            return
        echo_lines(results_lines(results, hist, floor_note))
