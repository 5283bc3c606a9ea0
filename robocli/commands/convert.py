"""``robocli convert``: a recording rewritten for another tool; a thin layer over
:func:`robocli.io.convert.convert` (``--ros2``: a ROS 2 bag)."""

from __future__ import annotations

from pathlib import Path

import typer

from robocli.commands._options import flag, overwrite_option


def convert(
    file: Path = typer.Argument(..., exists=True, dir_okay=False, metavar="IN.mcap",
                                help="The robocli recording; never written to."),
    out: Path = typer.Argument(..., metavar="OUT", help="OUT.mcap: one file; another name: a bag "
                               "folder."),  # fmt: skip
    ros2: bool = flag("--ros2", "Write a ROS 2 bag (the only target)."),
    overwrite: bool = overwrite_option("Replace OUT.mcap if it exists."),
) -> None:
    """Rewrite a recording as a ROS 2 bag (standard messages in CDR, REP 103/105) that
    ros2 bag play, rosbags and Foxglove read; OUT.mcap is one file, another name a bag
    folder with its metadata.yaml."""
    from robocli.io.convert import convert as run

    if not ros2:
        raise typer.BadParameter("name the target: --ros2 (a ROS 2 bag)")
    stats = run(file, out, overwrite=overwrite)
    skipped = sum(stats.skipped.values())
    left = f"; {skipped} messages of {len(stats.skipped)} unmapped channels left out" \
        if skipped else ""  # fmt: skip
    typer.echo(f"wrote {stats.written} ROS 2 messages on {len(stats.topics)} topics from "
               f"{stats.read} messages into {stats.path}{left}", err=True)  # fmt: skip
