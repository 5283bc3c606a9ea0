"""The ``--replay FILE.mcap``, ``--speed`` and ``--loop`` options of ``serve`` and ``sim``."""

from __future__ import annotations

from pathlib import Path

import typer

__all__ = ["LoopOpt", "ReplayOpt", "SpeedOpt", "check_replay"]

ReplayOpt = typer.Option(
    None, "--replay", metavar="FILE.mcap", dir_okay=False,
    help="Play this recording back instead of simulating.",
)  # fmt: skip
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
