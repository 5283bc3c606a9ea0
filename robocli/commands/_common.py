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
