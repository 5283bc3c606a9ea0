"""``robocli sim create``: the iRobot Create 2 simulator (Open Interface) on a pty or TCP.

A few lines over :class:`robocli.sim.create.CreateSim`; kept in its own module so the
command's options can change without touching the others'.
"""

from __future__ import annotations

from pathlib import Path

import typer

from robocli.commands import _common as common
from robocli.commands import _options as opt


def simulate(
    pty: bool = opt.flag("--pty", "Serve on a pseudo-terminal, as a serial port (the default)."),
    port: int | None = opt.port_option(None, "Serve on this TCP port instead (0: any)."),
    map_file: Path | None = opt.MapOpt,
    pose: str | None = opt.pose_option("Start pose in the map: m, m, rad."),
    bind: str = opt.bind_option("Address to listen on (TCP)."),
    time_scale: float = opt.TimeScaleOpt,
    bump_stops: bool = opt.flag("--bump-stops/--no-bump-stops", "A bump in safe mode stops the "
                                "wheels (the specification: wheel drops and cliffs only).", True),
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
    with common.sigterm_as_interrupt(), CreateSim(world=world, start_pose=start,
                                                  time_scale=time_scale,
                                                  bump_stops=bump_stops) as sim:  # fmt: skip
        if port is None:
            where = sim.serve_pty()
        else:
            with common.listening(bind):
                where = sim.serve_tcp(common.bind_address(bind), port)
        typer.echo(f"create: iRobot Create 2 (Open Interface) on {where}")
        common.wait_forever()
