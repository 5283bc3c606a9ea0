"""``robocli sim create``: the iRobot Create 2 simulator (Open Interface) on a pty or TCP.

A few lines over :class:`robocli.sim.create.CreateSim`; kept in its own module so the
command's options can change without touching the others'.
"""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import typer

from robocli.commands._common import SIM, bind_address, listening, sigterm_as_interrupt


def simulate(
    pty: bool = typer.Option(
        False, "--pty", help="Serve on a pseudo-terminal, as a serial port (the default)."
    ),
    port: int | None = typer.Option(
        None, "--port", "-p", min=0, max=65535, help="Serve on this TCP port instead (0: any)."
    ),
    map_file: Path | None = typer.Option(
        None, "--map", exists=True, dir_okay=False, help="Map: JSON or text walls (x1 y1 x2 y2)."
    ),
    pose: str | None = typer.Option(
        None, "--pose", metavar="X,Y,TH", help="Start pose in the map: m, m, rad."
    ),
    bind: str = typer.Option("127.0.0.1", "--bind", help="Address to listen on (TCP)."),
    time_scale: float = typer.Option(
        1.0, "--time-scale", min=0.1, max=100.0, help="Simulated seconds per wall second."
    ),
    bump_stops: bool = typer.Option(
        True,
        "--bump-stops/--no-bump-stops",
        help="A bump in safe mode stops the wheels (the specification: wheel drops and "
        "cliffs only).",
    ),
) -> None:
    """Run a simulated iRobot Create 2 speaking the Open Interface until Ctrl-C."""
    from robocli.commands.laser import _pose
    from robocli.commands.pioneer import _load_map
    from robocli.sim.create import CreateSim
    from robocli.sim.world import World

    if pty and port is not None:
        raise typer.BadParameter("give --pty or --port, not both", param_hint="'--port'")
    world = _load_map(World, map_file) if map_file else None
    start = _pose(pose) if pose else None
    with sigterm_as_interrupt(), CreateSim(world=world, start_pose=start, time_scale=time_scale,
                                           bump_stops=bump_stops) as sim:  # fmt: skip
        if port is None:
            where = sim.serve_pty()
        else:
            with listening(bind):
                where = sim.serve_tcp(bind_address(bind), port)
        typer.echo(f"create: iRobot Create 2 (Open Interface) on {where}")
        sys.stdout.flush()
        while True:
            time.sleep(3600)


@contextlib.contextmanager
def create_url(port: str) -> Iterator[str]:
    """``port`` itself, or for ``sim`` an embedded Create simulator on an ephemeral TCP
    port (closed when the block ends)."""
    if port != SIM:
        yield port
        return
    from robocli.sim.create import CreateSim

    with CreateSim() as sim:
        yield sim.serve_tcp("127.0.0.1", 0)


def connect_create(stack: contextlib.ExitStack, rec: Any, port: str, timeout: float) -> Any:
    """``record --create``: a Create recorded from its first byte; returns the device."""
    from robocli.devices.create import Create

    url = stack.enter_context(create_url(port))
    listener = rec.listener("create", "create-oi", url=url)
    robot = stack.enter_context(Create.connect(url, timeout=timeout, listeners=[listener]))
    rec.add(robot, listener.name)
    return robot
