"""``robocli urdf``: a robot's model for viewers (Foxglove, Lichtblick, RViz)."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from robocli.commands._options import OverwriteOpt, output_option


def urdf(
    name: str = typer.Argument(
        ..., help="Robot: a Pioneer subtype (p3dx...) or an arm model (irb120...)."
    ),
    out: Path | None = output_option(None, "Write to FILE (default: stdout)."),
    prefix: str = typer.Option("", "--prefix", help="Before every link name (e.g. 'pioneer/')."),
    overwrite: bool = OverwriteOpt,
) -> None:
    """Print the URDF of a robot, generated from robocli's own model of it."""
    from robocli.output import check_output, replace_output
    from robocli.robots.urdf import urdf as make

    if out is not None:
        check_output(out, overwrite)
    text = make(name, prefix)
    if out is None:
        sys.stdout.write(text)
        return
    with replace_output(out, overwrite, text=True) as fh:
        fh.write(text)
