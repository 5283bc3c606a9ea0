"""``robocli export``: a recording as one file per channel (CSV, JSON Lines, NPZ) or as the
IRB120 paper's JSON log of an arm, a thin layer over :func:`robocli.io.export.export`.
It prints each file written, one a line."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import typer

from robocli.commands._options import OverwriteOpt, output_option

#: What ``export`` writes (robocli.io.export.FORMATS; a test checks that they agree).
Format = Literal["csv", "jsonl", "npz", "irb120-json"]


def export(
    recording: Path = typer.Argument(..., exists=True, dir_okay=False, metavar="FILE",
                                     help="An MCAP recording."),
    fmt: Format = typer.Option(..., "--format", "-f", help="What to write."),
    out: Path | None = output_option(None, "Folder to write into (default: the recording's).",
                                     file_okay=False, metavar="DIR"),  # fmt: skip
    overwrite: bool = OverwriteOpt,
) -> None:
    """Export a recording: one file per channel, or an arm's IRB120 JSON log."""
    from robocli.io.export import export as run

    for path in run(recording, fmt, out, overwrite):
        typer.echo(str(path))
