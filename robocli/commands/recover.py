"""``robocli recover``: a recording cut short (killed, a full disk) rewritten whole, with
its summary, indexes and footer, so that every MCAP reader opens it; a thin layer over
:func:`robocli.io.record.recover`. It says on stderr what it kept."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path

import typer

from robocli.commands._options import output_option, overwrite_option


def recover(
    file: Path = typer.Argument(..., exists=True, dir_okay=False, metavar="FILE",
                                help="The recording to recover (.mcap); never written to."),
    out: Path | None = output_option(None, "File to write (default: FILE's name + .recovered).",
                                     metavar="OUT"),  # fmt: skip
    overwrite: bool = overwrite_option("Replace OUT if it exists."),
) -> None:
    """Rewrite every complete chunk and record of a recording that was killed or whose disk
    filled up into a new file with its summary, indexes and footer (as mcap recover does)."""
    from robocli.io.record import recover as run

    stats = run(file, out, overwrite=overwrite)
    cut = f", {stats.lost_bytes} bytes of a cut record dropped" if stats.truncated else ""
    skipped = f", {stats.skipped} malformed records left out" if stats.skipped else ""
    if stats.orphans:
        skipped += f", {stats.orphans} messages of undeclared channels left out"
    typer.echo(f"recovered {stats.messages} messages on {stats.channels} channels from "
               f"{stats.chunks} chunks{cut}{skipped} into {stats.path}", err=True)  # fmt: skip


@contextlib.contextmanager
def truncation_notes() -> Iterator[None]:
    """While the block runs, a reader that meets a recording cut short says so on stderr
    (one line naming ``robocli recover``) and goes on with what the file holds."""
    from robocli.io.record.mcapfile import truncation_notes as notes

    with notes(lambda hint: typer.echo(f"robocli: note: {hint}", err=True)):
        yield
