"""What the commands share: the embedded `sim` target, man-page help, quiet ends of pipes,
JSON Lines output (its data from :mod:`robocli.io.jsonlines`; signal handling, bind errors
and refusals from :mod:`robocli.running`, re-exported here)."""

from __future__ import annotations

import contextlib
import inspect
import json
import math
import re
import sys
from collections.abc import Callable, Iterable, Iterator, Sequence
from typing import Any, NoReturn

import typer
from typer.core import TyperCommand

from robocli.devices.pioneer.link import explain_refusal as explain_refusal
from robocli.io.jsonlines import RESOLUTION as RESOLUTION
from robocli.io.jsonlines import json_default
from robocli.io.jsonlines import rounded as rounded
from robocli.io.jsonlines import unix_stamped as unix_stamped
from robocli.running import listening as listening
from robocli.running import shielded as shielded
from robocli.running import sigterm_as_interrupt as sigterm_as_interrupt

SIM = "sim"


def from_env(ctx: typer.Context, name: str) -> bool:
    """Whether parameter ``name`` took its value from its environment variable (so that
    an explicit choice such as ``--file`` may override it without a conflict)."""
    source = ctx.get_parameter_source(name)
    return source is not None and source.name == "ENVIRONMENT"


def bind_address(text: str) -> str:
    """``--bind``: a host name, IPv4 or IPv6 address (brackets optional) to listen on; a
    usage error (exit 2) for anything else, a port included."""
    from robocli.transports import parse_host

    return parse_host(text, what="--bind")


_TYPE_HINT = re.compile(r"(?<=\S) <(int range|float range|[\w.-]+(?:\|[\w.-]+)*)>( *)")
#: What an option's value is called instead of Typer's ``<int range>``-style placeholder.
_VALUE_NAMES = {"int": "INTEGER", "float": "NUMBER", "int range": "INTEGER", "path": "PATH",
                "float range": "NUMBER", "file": "FILE", "str": "TEXT", "text": "TEXT"}  # fmt: skip


def _plain_type(match: re.Match[str]) -> str:
    """A placeholder as plain help shows it, the description after it staying in its column:
    nothing after a flag or an argument's name, ``INTEGER``-style after an option, the
    choices as ``[little|big]``."""
    kind, pad = match.group(1), match.group(2)
    name = match.string[: match.start()].rsplit(None, 1)[-1]  # `--port`, or `PORT`
    width = len(match.group())
    if kind == "bool" or not name.startswith("-"):
        return " " * width
    value = f" {_VALUE_NAMES[kind]}" if kind in _VALUE_NAMES else f" [{kind}]"  # choices
    if not pad:  # the description is on the next line
        return value
    return value.ljust(max(width, len(value) + 2))  # 2 spaces at least before the description


class PlainCommand(TyperCommand):
    """A command whose help reads like a man page: ``PORT`` (not ``{port}``) in the usage
    line, flags without ``<bool>``, option values named ``INTEGER``/``NUMBER``/``TEXT``."""

    def collect_usage_pieces(self, ctx: Any) -> list[str]:
        pieces = super().collect_usage_pieces(ctx)
        return [piece.replace("{", "").replace("}", "").upper() for piece in pieces]

    def parse_args(self, ctx: Any, args: list[str]) -> list[str]:
        """First, a number option given ``nan`` or ``inf`` is refused as not a finite number
        (the range check would say ``nan`` is above the maximum)."""
        if not ctx.resilient_parsing:
            from robocli.commands._options import renamed

            args = renamed(" ".join(ctx.command_path.split()[1:]), list(args))
            _check_finite(self, ctx, args)
        return super().parse_args(ctx, args)

    def invoke(self, ctx: Any) -> Any:
        """Run the command; a reader of stdout that left (``| head -n 2``) ends it quietly
        with exit code 0, whichever command printed (Typer would exit 1 without a word)."""
        with reader_may_leave():
            result = super().invoke(ctx)
            sys.stdout.flush()  # what is buffered meets the closed pipe here, not at exit
        return result

    def format_help(self, ctx: Any, formatter: Any) -> None:
        super().format_help(ctx, formatter)
        # one string: a placeholder and the padding after it are separate pieces of the buffer
        formatter.buffer[:] = [_TYPE_HINT.sub(_plain_type, "".join(formatter.buffer))]


def _check_finite(command: Any, ctx: Any, args: list[str]) -> None:
    """Raise a usage error for a float option given a value that is not a finite number."""
    floats = [
        p for p in command.params
        if getattr(getattr(p, "type_descriptor", None), "annotation", None) is float
    ]  # fmt: skip
    if not floats:
        return
    try:
        opts, _, _ = command.make_parser(ctx).parse_args(args=list(args))
    except typer.TyperException:
        return  # the real parse reports it
    for param in floats:
        values = opts.get(param.name)
        for value in values if isinstance(values, (list, tuple)) else [values]:
            try:
                number = float(value)
            except (TypeError, ValueError):
                continue  # not a number at all: the real parse says so
            if not math.isfinite(number):
                raise typer.BadParameter(f"{value!r} is not a finite number", ctx=ctx, param=param)




def bundled(
    name: str, options: Sequence[tuple[str, Any, Any]], bundle: Callable[..., Any]
) -> Callable[[Callable[..., None]], Callable[..., None]]:
    """Make a command of a function that takes one value, its parameter ``name``, for a
    group of options several commands share, given as ``(name, type, typer.Option)``: in the
    command's signature (what Typer reads), that parameter becomes those options, in its
    place (so that -h lists them there), and the function is called with
    ``bundle(**their values)`` for it."""
    names = [n for n, _, _ in options]

    def decorate(function: Callable[..., None]) -> Callable[..., None]:
        signature = inspect.signature(function, eval_str=True)
        if name not in signature.parameters:
            raise TypeError(f"{function.__qualname__} has no parameter {name!r} to replace")
        params: list[inspect.Parameter] = []
        for param in signature.parameters.values():
            shared = [inspect.Parameter(n, param.kind, default=option, annotation=kind)
                      for n, kind, option in options]  # fmt: skip
            params += shared if param.name == name else [param]

        def command(**values: Any) -> None:
            values[name] = bundle(**{n: values.pop(n) for n in names})
            function(**values)

        command.__name__, command.__doc__ = function.__name__, function.__doc__
        command.__module__, command.__qualname__ = function.__module__, function.__qualname__
        command.__signature__ = inspect.Signature(params)  # type: ignore[attr-defined]
        return command

    return decorate


@contextlib.contextmanager
def reader_may_leave() -> Iterator[None]:
    """Around output to a pipe: when its reader goes away (``robocli dump ... | head``),
    stop quietly with exit code 0 (stdout goes to /dev/null, so that the final flush
    does not complain)."""
    try:
        yield
    except BrokenPipeError:
        stdout_to_devnull()
        raise typer.Exit(0) from None


def wait_forever() -> NoReturn:
    """Flush stdout and block until Ctrl-C or SIGTERM: a server runs in its own threads."""
    import time

    sys.stdout.flush()
    while True:
        time.sleep(3600)


def stdout_to_devnull() -> None:
    """Point stdout at /dev/null, so that the interpreter's last flush of what a reader that
    left did not take neither fails nor says so."""
    import os

    with contextlib.suppress(OSError, ValueError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())


def print_json(data: Any) -> None:
    """``data`` as one line of JSON on stdout (``--json`` is JSON Lines everywhere, ``--once``
    included; round floats first with :func:`rounded`)."""
    typer.echo(json.dumps(data, default=json_default, allow_nan=True))


def echo_lines(lines: Iterable[str]) -> None:
    """Each of ``lines`` on stdout (a view's text: :mod:`robocli.views`)."""
    for line in lines:
        typer.echo(line)
