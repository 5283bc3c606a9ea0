"""``robocli plot``: a figure of a recording, a thin layer over
:func:`robocli.io.record.plot.plot` (matplotlib:
``pip install 'robocli-robots[plot]'``)."""

from __future__ import annotations

from pathlib import Path

import typer

from robocli.commands._common import print_json
from robocli.commands._options import OverwriteOpt, RecordingArg, json_option, output_option


def plot(
    file: Path = RecordingArg,
    channel: list[str] = typer.Option(..., "--channel", "-c", metavar="TOPIC", help="A channel to "
                                      "draw (repeatable): a pose (the path, with the scan "
                                      "channels given beside it), joint states, or any channel "
                                      "with --field."),  # fmt: skip
    field: list[str] = typer.Option([], "--field", "-f", metavar="A.B", help="A numeric field to "
                                    "draw against time (repeatable), e.g. "
                                    "linear_acceleration.z."),  # fmt: skip
    output: Path = output_option(..., "The figure (PNG).", dir_okay=False, metavar="OUT.png"),
    title: str | None = typer.Option(None, "--title", help="A title over the figure."),
    overwrite: bool = OverwriteOpt,
    json_out: bool = json_option(),
) -> None:
    """Draw a recording's channels into a PNG: a Pioneer's path with its sonar or laser
    returns, an arm's joints against time, or any numeric field against time."""
    from robocli.io.record.plot import plot as draw

    result = draw(file, output, channel, field, title=title, overwrite=overwrite)
    if json_out:
        print_json(result.as_dict())
        return
    drawn = ", ".join(f"{name} ({n})" for name, n in result.series.items())
    scans = f"; {result.scan_points} scan returns" if result.scan_points else ""
    typer.echo(f"plot written: {result.path} ({result.kind}: {drawn}{scans}; "
               f"{result.duration_s:.1f} s)")  # fmt: skip
