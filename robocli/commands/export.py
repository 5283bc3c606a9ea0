"""``robocli export``: a recording as one file per channel (CSV, JSON Lines, NPZ) or as the
IRB120 paper's JSON log of an arm, a thin layer over :func:`robocli.io.export.export`.
It prints each file written, one a line."""

from __future__ import annotations

from pathlib import Path

import typer

from robocli.commands._common import OverwriteOpt
from robocli.io.export import FORMATS


def export(
    recording: Path = typer.Argument(
        ..., exists=True, dir_okay=False, metavar="FILE", help="An MCAP recording."
    ),
    fmt: str = typer.Option(
        ..., "--format", "-f", metavar="|".join(FORMATS), help="What to write."
    ),
    out: Path | None = typer.Option(  # noqa: UP007
        None,
        "--output",
        "-o",
        file_okay=False,
        metavar="DIR",
        help="Folder to write into (default: the recording's).",
    ),
    overwrite: bool = OverwriteOpt,
) -> None:
    """Export a recording: one file per channel, or an arm's IRB120 JSON log."""
    from robocli.io.export import export as run

    if fmt not in FORMATS:
        raise typer.BadParameter(f"choose from {', '.join(FORMATS)}, not {fmt!r}",
                                 param_hint="'--format'")  # fmt: skip
    for path in run(recording, fmt, out, overwrite):
        typer.echo(str(path))
