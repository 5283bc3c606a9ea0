"""Whole benchmark runs, as ``robocli bench`` makes them: the stages in order, each pinned
and fed its own device or simulator, Ctrl-C keeping what was measured. The command only
parses, calls one of these and renders the :class:`Outcome` (``stage`` shows progress; the
library never prints).

- :func:`pioneer_rtt`: the C ping-pong floor (one CPU, then two), then CONFIG round trips:
  against ``url``, or a bare socket and the client against a C ARCOS responder and the client
  against the simulator in its own process;
- :func:`arm_bench`: JOINT_TRAJ_PT round trips after the floor, or the state period, against
  ``url`` or the ABB simulator in its own process (Table 5 of the IRB120 paper);
- :func:`sip_timing` and :func:`laser_timing`: a Pioneer's SIPs, a Hokuyo's scans;
- :func:`hub_rtt` and :func:`hub_throughput`: a sensor hub's pulls.
"""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

from robocli.bench import harness as bh
from robocli.bench.stats import Run
from robocli.errors import InvalidArgument, TransportError

#: ``stage(label, total)``: a context whose value is called with the count done so far.
Stage = Callable[[str, int], contextlib.AbstractContextManager[Callable[[int], None]]]
#: Multiples of the same-CPU floor (median, p99) the client must stay under.
RESPONDER_TARGETS = (3.0, 6.0)
SIM_TARGETS = (6.0, 15.0)


@contextlib.contextmanager
def no_progress(label: str, total: int) -> Iterator[Callable[[int], None]]:
    yield lambda done: None


@dataclass
class Outcome:
    """What a run measured: each stage's :class:`Run` with its targets (multiples of the
    floor, or None), and whether Ctrl-C ended it early."""

    runs: list[tuple[Run, tuple[float, float] | None]] = field(default_factory=list)
    interrupted: bool = False
    where: str = ""

    def stage(self, name: str, n: int, where: str = "",
              targets: tuple[float, float] | None = None) -> Run:  # fmt: skip
        run = Run(name, n, where)
        self.runs.append((run, targets))
        return run

    @property
    def samples(self) -> int:
        return sum(run.count for run, _ in self.runs)


def cpus(cpu: int | None) -> tuple[int | None, int | None]:
    """(the CPU both ends share, another CPU for the cross-CPU floor), None where pinning is
    impossible (another platform, or a single allowed CPU for the second)."""
    allowed = bh.allowed_cpus()
    if not allowed:
        return None, None
    if cpu is not None and cpu not in allowed:
        raise InvalidArgument(f"--cpu: CPU {cpu} is not available; allowed: {allowed}")
    same = allowed[0] if cpu is None else cpu
    return same, next((c for c in allowed if c != same), None)


def _floors(out: Outcome, n: int, same: int | None, other: int | None, stage: Stage) -> None:
    at = bh.cpu_label
    run = out.stage("C floor, same CPU", n, f"both ends on {at(same)}")
    with stage(run.name, n) as update:
        bh.c_floor(run, same, same, progress=update)
    if other is not None:
        run = out.stage("C floor, different CPUs", n, f"ends on {at(same)} and {at(other)}")
        with stage(run.name, n) as update:
            bh.c_floor(run, same, other, progress=update)


def pioneer_rtt(url: str | None, n: int, floor_n: int | None = None, cpu: int | None = None,
                stage: Stage = no_progress) -> Outcome:  # fmt: skip
    """CONFIG round trips of a Pioneer at ``url`` (None: the responder and the simulator
    process), after the C floor; the first run is the same-CPU floor."""
    from robocli.bench import pioneer as bp

    same, other = cpus(cpu)
    at = bh.cpu_label
    out = Outcome()
    try:
        _floors(out, floor_n or n, same, other, stage)
        if url is not None:
            run = out.stage(f"pioneer CONFIG, {url}", n, f"client on {at(same)}")
            with stage(run.name, n) as update, bh.pinned(same), bp.pioneer_at(url) as robot:
                bp.pioneer_rtt(robot, run, progress=update)
            return out
        run = out.stage("bare socket vs C responder", n, f"both on {at(same)}")
        with stage(run.name, n) as update, bh.pinned(same):
            with bp.arcos_responder(same) as responder:
                bp.bare_rtt(responder.port, run, progress=update)
        run = out.stage("client vs C responder", n, f"client, responder on {at(same)}",
                        RESPONDER_TARGETS)  # fmt: skip
        with stage(run.name, n) as update, bh.pinned(same):
            with bp.arcos_responder(same) as responder, \
                    bp.pioneer_on_responder(responder) as robot:  # fmt: skip
                bp.pioneer_rtt(robot, run, progress=update)
        run = out.stage("client vs simulator process", n, f"client, simulator on {at(same)}",
                        SIM_TARGETS)  # fmt: skip
        with stage(run.name, n) as update, bh.pinned(same):
            with pioneer_sim_process(same) as sim_url, bp.pioneer_at(sim_url) as robot:
                bp.pioneer_rtt(robot, run, progress=update)
    except KeyboardInterrupt:
        out.interrupted = True
    return out


def arm_bench(kind: str, url: str | None, n: int, paper: bool = False,
              floor_n: int | None = None, cpu: int | None = None,
              wire: tuple[str, int] = ("little", 4),
              stage: Stage = no_progress) -> Outcome:  # fmt: skip
    """``kind`` ``rtt``: JOINT_TRAJ_PT round trips after the C floor; ``jitter``: the state
    period; against ``url`` or the built-in ABB simulator in its own process (``paper``: its
    paper-like model). ``wire``: (byte order, real size) of the controller, and of that
    simulator. :attr:`Outcome.where` names what was measured."""
    from robocli.bench import arm as ab
    from robocli.devices.arm import Arm

    if url is not None and paper:
        raise InvalidArgument("--paper-model configures the built-in simulator; not with a URL")
    same, other = cpus(cpu) if kind == "rtt" else (None, None)
    variant = "" if wire == ("little", 4) else f", {wire[0]}-endian, {wire[1] * 8}-bit reals"
    out = Outcome(where=(url or f"ABB simulator process{', paper model' if paper else ''}")
                  + variant)  # fmt: skip
    name = "JOINT_TRAJ_PT -> reply" if kind == "rtt" else "state period"
    try:
        if kind == "rtt":
            _floors(out, floor_n or n, same, other, stage)
        run = out.stage(name, n, f"{out.where}; client on {bh.cpu_label(same)}")
        with contextlib.ExitStack() as stack:
            stack.enter_context(bh.pinned(same))
            h, mp, sp = (ab.parse_url(url) if url is not None else stack.enter_context(
                ab.sim_process(paper, cpu=same, wire=wire)))  # fmt: skip
            arm = stack.enter_context(Arm.connect(
                h, mp, sp, motion=kind == "rtt", byte_order=wire[0],
                real_size=wire[1]))  # fmt: skip
            update = stack.enter_context(stage(name, n))
            (ab.rtt if kind == "rtt" else ab.state_periods)(arm, run, progress=update)
    except KeyboardInterrupt:
        out.interrupted = True
    return out


def sip_timing(url: str | None, n: int,
               stage: Stage = no_progress) -> tuple[dict[str, Any], bool]:  # fmt: skip
    """A Pioneer's SIP timing through the client (``url`` None: an embedded simulator);
    what was collected, and whether Ctrl-C ended it."""
    from robocli.bench import pioneer as bp

    timing: dict[str, Any] = {}
    try:
        with contextlib.ExitStack() as stack:
            where = url if url is not None else stack.enter_context(_embedded_pioneer())
            update = stack.enter_context(stage("SIPs", n))
            bp.pioneer_sip_timing(where, n, progress=update, into=timing)
    except KeyboardInterrupt:
        return timing, True
    return timing, False


def laser_timing(url: str | None, n: int,
                 stage: Stage = no_progress) -> tuple[dict[str, Any], bool]:  # fmt: skip
    """A Hokuyo's streamed scans (``url`` None: the embedded UTM-30LX simulator, 25 ms)."""
    from robocli.bench.laser import laser_scan_timing

    timing: dict[str, Any] = {}
    try:
        with contextlib.ExitStack() as stack:
            if url is None:
                from robocli.sim.hokuyo import HokuyoSim

                url = stack.enter_context(HokuyoSim("utm-30lx")).serve_tcp("127.0.0.1", 0)
            update = stack.enter_context(stage("scans", n))
            laser_scan_timing(url, n, progress=update, into=timing)
    except KeyboardInterrupt:
        return timing, True
    return timing, False


@contextlib.contextmanager
def hub_at(url: str | None) -> Iterator[tuple[str, Any]]:
    """(``url``'s address, None), else a simulated hub in its own process (its address,
    its :class:`~robocli.bench.hub.HubProcess`)."""
    from robocli.bench.hub import hub_process

    if url is not None:
        from robocli.devices.hub.client import parse_hub
        from robocli.transports import format_address

        yield format_address(*parse_hub(url)), None
        return
    with hub_process() as proc:
        yield proc.address, proc


def hub_rtt(url: str | None, n: int) -> Outcome:
    """Empty-pull round trips of a hub through the client (``url`` None: a simulated hub in
    its own process); one run."""
    from robocli.bench import hub as hub_bench

    out = Outcome()
    run = out.stage("hub empty pull", n)
    try:
        with hub_at(url) as (address, _proc):
            run.where = f"hub {address}" + ("" if url else " (simulated, own process)")
            hub_bench.rtt(address, run)
    except KeyboardInterrupt:
        out.interrupted = True
    return out


def hub_throughput(url: str | None, clients: int, sensors: str, seconds: float,
                   pull_hz: float, workers: int | None) -> dict[str, Any]:  # fmt: skip
    """Many clients pulling ``sensors`` (comma-separated) of a hub: the report of
    :func:`robocli.bench.hub.throughput`. An unknown sensor is an :class:`InvalidArgument`."""
    from robocli.bench import hub as hub_bench

    names = tuple(s.strip() for s in sensors.split(",") if s.strip())
    unknown = [s for s in names if s not in hub_bench.BENCH_SENSORS]
    if unknown or not names:
        raise InvalidArgument(f"--sensors: {unknown[0] if unknown else sensors!r} unknown; "
                              f"choose from {', '.join(hub_bench.BENCH_SENSORS)}")  # fmt: skip
    with hub_at(url) as (address, proc):
        return hub_bench.throughput(
            address, clients=clients, sensors=names, seconds=seconds, pull_hz=pull_hz,
            workers=workers, hub=proc, served=hub_bench.served_sensors(address),
        )  # fmt: skip


@contextlib.contextmanager
def _embedded_pioneer() -> Iterator[str]:
    from robocli.sim.pioneer.server import PioneerSim

    with PioneerSim() as simulator:
        yield simulator.serve_tcp("127.0.0.1", 0)


@contextlib.contextmanager
def pioneer_sim_process(cpu: int | None = None, timeout: float = 20.0) -> Iterator[str]:
    """Yield the URL of a Pioneer simulator running in its own process (pinned to ``cpu``
    when given), so that a benchmark measures the client against a server that does not
    share its interpreter. The child ignores Ctrl-C (the parent stops it: end of its stdin,
    then SIGTERM, then SIGKILL, each bounded)."""
    code = "from robocli.bench.runs import sim_child_main; sim_child_main()"
    with bh.child_process(code, "" if cpu is None else str(cpu), timeout=timeout) as (_, line):
        if not line.startswith("tcp://"):
            raise TransportError(
                f"the simulator process did not start within {timeout:g} s"
                + (f": {line}" if line else "")
            )
        yield line


def sim_child_main() -> None:
    """The process of :func:`pioneer_sim_process`: ``argv[1]`` is the CPU to pin to (or
    empty); prints the simulator's URL, serves until its stdin ends."""
    import os
    import sys

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the parent; it stops us
    cpu = sys.argv[1] if len(sys.argv) > 1 else ""
    if cpu and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {int(cpu)})  # before any thread starts: they all inherit it
    from robocli.sim.pioneer.server import PioneerSim

    with PioneerSim() as simulator:
        sys.stdout.write(simulator.serve_tcp("127.0.0.1", 0) + "\n")  # the parent reads it
        sys.stdout.flush()
        bh.wait_for_stdin_eof()  # until the parent closes the pipe (or dies)
