"""MkDocs hook: the CLI reference page is written from the Typer app at build time.

``docs/cli.md`` holds the marker ``<!-- cli-reference -->``; this hook replaces it with one
section per command, each the exact help text ``robocli COMMAND -h`` prints, so the page
cannot drift from the code. Groups (``connect``, ``sim``...) come before their commands.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

MARKER = "<!-- cli-reference -->"
WIDTH = 100


def _walk(cmd: Any, parent: Any, name: str) -> Iterator[tuple[str, Any]]:
    """(command path, context) of ``cmd`` and of every command below it. Typer carries its
    own copy of click, so the classes are the command's own (``context_class``)."""
    ctx = cmd.context_class(cmd, info_name=name, parent=parent, terminal_width=WIDTH,
                            max_content_width=WIDTH)  # fmt: skip
    yield ctx.command_path, ctx
    if hasattr(cmd, "list_commands"):
        for sub in cmd.list_commands(ctx):
            child = cmd.get_command(ctx, sub)
            if child is not None and not child.hidden:
                yield from _walk(child, ctx, sub)


def reference() -> str:
    """The Markdown of every command's help, in the app's order."""
    import typer

    from robocli.cli import app

    root = typer.main.get_command(app)
    out = []
    for path, ctx in _walk(root, None, "robocli"):
        level = "#" * min(2 + path.count(" "), 4)
        anchor = path.replace(" ", "-")
        out.append(f"{level} `{path}` {{#{anchor}}}\n\n```text\n{ctx.get_help()}\n```\n")
    return "\n".join(out)


def on_page_markdown(markdown: str, page: Any, **_: Any) -> str:
    if MARKER in markdown:
        return markdown.replace(MARKER, reference())
    return markdown
