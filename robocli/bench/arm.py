"""The arm's Table-5 measurements, through the real client: JOINT_TRAJ_PT request ->
SERVICE_REPLY round trips (:func:`rtt`) and the state period (:func:`state_periods`).

The IRB120 paper's Table 5 measured both between MATLAB/ROS and the controller: RTT mean
33.9 ms (median 31.8, std 6.76, min 20.4, max 65.8) and a StateServer period of mean 20.3 ms
(median 15.7, std 18.0, min 0.5, max 63.0); :data:`PAPER_TABLE5` holds them. The statistics
are :class:`robocli.bench.stats.SampleStats` (Table 5's plus p90/p99), filled into a
:class:`robocli.bench.stats.Run` as they come, so Ctrl-C keeps what was measured.

Round trips never move the arm: each is a download start (sequence -1) at the measured
joints, which an ABB buffers and never runs without a -3; a streaming server (which answers
FAILURE to -1) gets sequence 0 at the measured joints instead, a move to where it is.
:func:`sim_process` runs the built-in ABB simulator in its own process, as the Pioneer bench
runs its simulator, optionally with the paper-like controller model.
"""

from __future__ import annotations

import contextlib
import json
import sys
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any

import numpy as np

from robocli.bench.harness import child_process, wait_for_stdin_eof
from robocli.bench.stats import Run
from robocli.errors import DeviceError, TransportError
from robocli.protocols.simple_message import PORT_MOTION, SpecialSeq
from robocli.transports import parse_address

if TYPE_CHECKING:
    from robocli.devices.arm import Arm, JointSample

__all__ = ["PAPER_TABLE5", "parse_url", "rtt", "sim_process", "state_periods"]

Progress = Callable[[int], None]

#: The paper's Table 5 (ms): name -> mean, median, std, min, max.
PAPER_TABLE5 = {
    "rtt": {"mean": 33.9, "median": 31.8, "std": 6.76, "min": 20.4, "max": 65.8},
    "state period": {"mean": 20.3, "median": 15.7, "std": 18.0, "min": 0.5, "max": 63.0},
}
#: The simulator's state period in the benches (ms): the paper's, not the stock 100 ms.
BENCH_STATE_MS = 20.0


def parse_url(url: str) -> tuple[str, int, int]:
    """``HOST``, ``HOST:MOTION``, ``[IPv6]:MOTION`` or ``tcp://HOST:MOTION`` -> (host,
    motion port, state port) by :func:`robocli.transports.parse_address`; the state port
    is the motion port + 2, as on an ABB (11000, 11002)."""
    host, motion = parse_address(url, PORT_MOTION, what="--url", form="HOST or HOST:MOTION_PORT",
                                 port_range=(1, 65533))  # fmt: skip
    return host, motion, motion + 2


def rtt(arm: Arm, run: Run, warmup: int = 5, progress: Progress | None = None,
        timeout: float = 5.0) -> Run:  # fmt: skip
    """Fill ``run`` with JOINT_TRAJ_PT request -> SERVICE_REPLY round trips (s) through
    :meth:`Arm.send_point`, after ``warmup`` unrecorded ones. Needs the state port (the
    points are the measured joints)."""
    q = arm.wait_for_state(timeout).joints
    seq = int(SpecialSeq.START_TRAJECTORY_DOWNLOAD)
    try:
        arm.send_point(seq, q, timeout=timeout)
    except DeviceError:  # a streaming server refuses -1: stream "stay here" instead
        seq = 0
    for _ in range(warmup):
        arm.send_point(seq, q, timeout=timeout)
    while run.count < run.n:
        run.samples[run.count] = arm.send_point(seq, q, timeout=timeout)
        run.count += 1
        if progress is not None and run.count % 16 == 0:
            progress(run.count)
    return run


def state_periods(arm: Arm, run: Run, progress: Progress | None = None,
                  timeout: float = 5.0) -> Run:  # fmt: skip
    """Fill ``run`` with the periods (s) between JOINT_POSITION messages as the client
    receives them (its receive stamps); every wait bounded by ``timeout``."""
    stamps: list[float] = []

    def on_sample(sample: JointSample) -> None:
        if sample.source == "joint_position" and len(stamps) <= run.n:
            stamps.append(sample.t)

    arm.add_listener(on_sample, kind="samples")
    try:
        while len(stamps) <= run.n:
            arm.wait_for_state(timeout)
            if progress is not None:
                progress(max(0, len(stamps) - 1))
    finally:
        arm.remove_listener(on_sample, kind="samples")
        periods = np.diff(np.array(stamps[: run.n + 1], dtype=np.float64))
        run.samples[: periods.size] = periods
        run.count = int(periods.size)
    return run


@contextlib.contextmanager
def sim_process(paper: bool = False, state_ms: float = BENCH_STATE_MS, profile: str = "abb",
                cpu: int | None = None, timeout: float = 20.0,
                wire: tuple[str, int] = ("little", 4),
                ) -> Iterator[tuple[str, int, int]]:  # fmt: skip
    """Yield ``(host, motion port, state port)`` of an ABB simulator in its own process
    (pinned to ``cpu`` when given; ``paper``: the paper-like controller model; ``wire``:
    its byte order, ``"little"`` or ``"big"``, and real size, 4 or 8). The child stops at
    the end of its stdin; it is terminated, then killed, if it does not."""
    options = {
        "paper": paper,
        "state_ms": state_ms,
        "profile": profile,
        "cpu": cpu,
        "byteorder": ">" if wire[0] == "big" else "<",
        "real": 8 if wire[1] == 8 else 4,
    }
    code = "from robocli.bench.arm import _child_main; _child_main()"
    with child_process(code, json.dumps(options), timeout=timeout) as (_, first):
        line = first.split()
        if len(line) != 3:
            raise TransportError(f"the ABB simulator process did not start within {timeout:g} s")
        yield line[0], int(line[1]), int(line[2])


def _child_main() -> None:
    """The process of :func:`sim_process`: prints ``host motion state``, serves until its
    stdin ends."""
    import os
    import signal

    from robocli.sim.abb.server import AbbSim, ControllerModel

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent stops us
    options: dict[str, Any] = json.loads(sys.argv[1])
    if options["cpu"] is not None and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {int(options["cpu"])})
    model = ControllerModel.paper() if options["paper"] else None
    with AbbSim(profile=options["profile"], state_ms=options["state_ms"], model=model,
                byteorder=options["byteorder"], real=options["real"]) as sim:  # fmt: skip
        motion, state = sim.serve_tcp("127.0.0.1", 0, 0)
        ports = [u.rsplit(":", 1)[1] for u in (motion, state)]
        print("127.0.0.1", *ports, flush=True)
        wait_for_stdin_eof()
