"""What the commands share: the embedded `sim` target, signal handling, JSON output."""

from __future__ import annotations

import contextlib
import json
import signal
from collections.abc import Iterator
from typing import Any

import typer

SIM = "sim"
PORT_HELP = (
    "Robot port or URL: /dev/ttyUSB0, COM1, tcp://HOST:8101, HOST:PORT, a pyserial URL, "
    "or 'sim' for an embedded simulator."
)


@contextlib.contextmanager
def pioneer_url(port: str, **sim_options: Any) -> Iterator[str]:
    """Yield a URL for ``port``; for ``sim`` start an in-process simulator on an ephemeral
    loopback port and stop it afterwards (the CLI, not the client, knows simulators)."""
    if port != SIM:
        yield port
        return
    from robocli.sim.pioneer import PioneerSim

    with PioneerSim(**sim_options) as simulator:
        yield simulator.serve_tcp("127.0.0.1", 0)


@contextlib.contextmanager
def pioneer_sim_process(cpu: int | None = None, timeout: float = 20.0) -> Iterator[str]:
    """Yield the URL of a Pioneer simulator running in its own process (pinned to ``cpu``
    when given), so that a benchmark measures the client against a server that does not
    share its interpreter. The child ignores Ctrl-C (the parent stops it: end of its stdin,
    then SIGTERM, then SIGKILL, each bounded)."""
    import selectors
    import subprocess
    import sys

    from robocli.errors import TransportError

    code = "from robocli.commands._common import sim_child_main; sim_child_main()"
    args = [sys.executable, "-c", code, "" if cpu is None else str(cpu)]
    proc = subprocess.Popen(
        args, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, start_new_session=True
    )
    assert proc.stdin is not None and proc.stdout is not None  # both are pipes
    try:
        with selectors.DefaultSelector() as sel:
            sel.register(proc.stdout, selectors.EVENT_READ)
            ready = sel.select(timeout)
        line = proc.stdout.readline().strip() if ready else ""
        if not line.startswith("tcp://"):
            raise TransportError(
                f"the simulator process did not start within {timeout:g} s"
                + (f": {line}" if line else "")
            )
        yield line
    finally:
        with contextlib.suppress(OSError):
            proc.stdin.close()  # the child stops at the end of its stdin
        try:
            proc.wait(0.5)  # a serving child exits at once; one still starting is terminated
        except subprocess.TimeoutExpired:
            proc.terminate()
            try:
                proc.wait(1.0)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(1.0)
        proc.stdout.close()


def sim_child_main() -> None:
    """The process of :func:`pioneer_sim_process`: ``argv[1]`` is the CPU to pin to (or
    empty); prints the simulator's URL, serves until its stdin ends."""
    import os
    import sys

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the parent; it stops us
    cpu = sys.argv[1] if len(sys.argv) > 1 else ""
    if cpu and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {int(cpu)})  # before any thread starts: they all inherit it
    from robocli.sim.pioneer import PioneerSim

    with PioneerSim() as simulator:
        print(simulator.serve_tcp("127.0.0.1", 0), flush=True)
        sys.stdin.read()  # until the parent closes the pipe (or dies)


@contextlib.contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """Let `kill` (SIGTERM) stop a command the way Ctrl-C does: robots stop, ports close."""

    def _raise(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    try:
        previous = signal.signal(signal.SIGTERM, _raise)
    except ValueError:  # not the main thread (e.g. called from a test runner thread)
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def print_json(data: Any) -> None:
    typer.echo(json.dumps(data, indent=2, default=_json_default, allow_nan=True))


def _json_default(obj: Any) -> Any:
    if hasattr(obj, "tolist"):
        return obj.tolist()
    if isinstance(obj, (set, frozenset, tuple)):
        return list(obj)
    return str(obj)
