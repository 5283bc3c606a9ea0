"""The ``--replay FILE.mcap``, ``--speed`` and ``--loop`` options of ``serve`` and ``sim``."""

from __future__ import annotations

from pathlib import Path

import typer

from robocli.commands._common import bind_address, listening, sigterm_as_interrupt, wait_forever

__all__ = ["LoopOpt", "ReplayOpt", "SpeedOpt", "abb_replay", "check_replay"]

ReplayOpt = typer.Option(None, "--replay", metavar="FILE.mcap", exists=True, dir_okay=False,
                         help="Play this recording back instead of simulating.")  # fmt: skip
SpeedOpt = typer.Option(None, "--speed", help="Replay speed (default 1).")
LoopOpt = typer.Option(False, "--loop", help="Replay again from the start at the end.")


def check_replay(replay: Path | None, speed: float | None, loop: bool) -> float:
    """The replay speed (1 by default); a usage error for ``--speed``/``--loop`` without
    ``--replay``, or a speed that is not positive."""
    if replay is None and (speed is not None or loop):
        raise typer.BadParameter("--speed and --loop go with --replay FILE",
                                 param_hint="'--speed'/'--loop'")  # fmt: skip
    if speed is not None and not 0 < speed < float("inf"):
        raise typer.BadParameter(f"must be > 0, not {speed:g}", param_hint="'--speed'")
    return 1.0 if speed is None else speed


def abb_replay(replay: Path, speed: float, loop: bool, robot: str, profile: str, bind: str,
               motion_port: int, state_port: int) -> None:  # fmt: skip
    """``sim abb --replay``: the recording's state stream on the state port until Ctrl-C."""
    from robocli.io.record.replay import RecordedPackets
    from robocli.sim.abb.replay import AbbReplay

    recorded = RecordedPackets(replay)
    with sigterm_as_interrupt(), AbbReplay(recorded, speed=speed, loop=loop, robot=robot,
                                           profile=profile) as simulator:  # fmt: skip
        with listening(bind):
            motion, state = simulator.serve_tcp(bind_address(bind), motion_port, state_port)
        typer.echo(f"replaying {replay}: motion {motion}, state {state}")
        wait_forever()  # Ctrl-C, SIGTERM: the simulator closes, exit 130
