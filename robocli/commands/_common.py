"""What the commands share: the embedded `sim` target, connecting with the reasons a robot
refuses spelled out, signal handling, JSON output rounded to the protocol's resolution."""

from __future__ import annotations

import contextlib
import inspect
import json
import math
import re
import signal
import sys
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import typer
from typer.core import TyperCommand

SIM = "sim"
PORT_HELP = (
    "Robot port or URL: /dev/ttyUSB0, COM1, tcp://HOST:8101, HOST:PORT, a pyserial URL, "
    "or 'sim' for an embedded simulator."
)


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


#: Every command that writes a user's file takes it (see :mod:`robocli.output`).
OverwriteOpt = typer.Option(False, "--overwrite", help="Replace an existing output file.")


def bundled(
    name: str, options: Sequence[inspect.Parameter], bundle: Callable[..., Any]
) -> Callable[[Callable[..., None]], Callable[..., None]]:
    """Make a command of a function that takes one value, its parameter ``name``, for a
    group of options several commands share: in the command's signature (what Typer reads),
    that parameter becomes ``options``, in its place (so that -h lists them there), and the
    function is called with ``bundle(**their values)`` for it."""
    names = [p.name for p in options]

    def decorate(function: Callable[..., None]) -> Callable[..., None]:
        signature = inspect.signature(function, eval_str=True)
        if name not in signature.parameters:
            raise TypeError(f"{function.__qualname__} has no parameter {name!r} to replace")
        params: list[inspect.Parameter] = []
        for param in signature.parameters.values():
            shared = [p.replace(kind=param.kind) for p in options]
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
def sigterm_as_interrupt() -> Iterator[None]:
    """Let `kill` (SIGTERM) stop a command the way Ctrl-C does: robots stop, ports close."""

    def _raise(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    try:
        previous = signal.signal(signal.SIGTERM, _raise)
    except ValueError:  # not the main thread (e.g. called from a test runner thread)
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextlib.contextmanager
def shielded() -> Iterator[None]:
    """Ctrl-C and SIGTERM are ignored inside (a bounded step, such as writing a recording
    on the way out): a second Ctrl-C must not leave the file half written."""
    try:
        saved = [(s, signal.signal(s, signal.SIG_IGN)) for s in (signal.SIGINT, signal.SIGTERM)]
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        for sig, handler in saved:
            signal.signal(sig, handler)


@contextlib.contextmanager
def listening(address: str) -> Iterator[None]:
    """Around a server's bind on ``address`` (``sim``, ``serve``, ``dump --listen``): a port
    already in use is no robot out of reach (exit 3) but a failure (exit 1); an address that
    is not this machine's, or no address at all, a usage error (exit 2)."""
    import errno
    import socket

    from robocli.errors import InvalidArgument, RobocliError, TransportError

    try:
        yield
    except InvalidArgument:
        raise
    except UnicodeError as exc:  # the IDNA codec of the resolver: an empty label ("a..b")
        why = str(exc.__cause__ or exc.__context__ or exc).removeprefix("UnicodeError: ")
        raise InvalidArgument(f"cannot listen on {address!r}: not a host name ({why})") from None
    except TransportError as exc:
        cause = exc.__cause__
        if isinstance(cause, (socket.gaierror, UnicodeError)) or (
            isinstance(cause, OSError) and cause.errno == errno.EADDRNOTAVAIL
        ):
            raise InvalidArgument(
                f"{exc} (give an address of this machine, e.g. 127.0.0.1)"
            ) from None
        raise RobocliError(str(exc)) from None


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


def stdout_to_devnull() -> None:
    """Point stdout at /dev/null, so that the interpreter's last flush of what a reader that
    left did not take neither fails nor says so."""
    import os

    with contextlib.suppress(OSError, ValueError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())


@contextlib.contextmanager
def explain_refusal(url: str) -> Iterator[None]:
    """Around connecting: a link reset or closed by the peer during the handshake becomes
    the :class:`DeviceError` of :func:`~robocli.devices.pioneer.link.busy_refusal` (the
    Pioneer's handshake does this itself; other paths may lose the link around it)."""
    from robocli.devices.pioneer.link import busy_refusal
    from robocli.errors import ConnectionLost

    try:
        yield
    except ConnectionLost as exc:
        raise busy_refusal(url, exc) or exc from None


#: Decimals kept in JSON output, by field name: the protocol's resolution in SI units
#: (odometry 0.485 mm and 2*pi/4096 rad, speeds 1 mm/s and 0.1 deg/s, battery 0.1 V...).
RESOLUTION = {
    "t": 6, "t_mono": 6, "x": 4, "y": 4, "th": 4, "v": 3, "w": 4, "left_velocity": 3,
    "right_velocity": 3, "battery": 1, "state_of_charge": 2, "sonar": 3, "analog": 3,
    "temperature": 1, "ranges": 3, "angles": 4, "range": 3, "angle": 4,
}  # fmt: skip


def rounded(data: Any, digits: int = 6, resolution: dict[str, int] = RESOLUTION) -> Any:
    """``data`` with every float rounded to its field's decimals in ``resolution`` (else
    ``digits``): no ``0.9590000000000001`` noise in JSON. NaN and infinities become None."""
    if isinstance(data, float):
        return round(data, digits) if math.isfinite(data) else None
    if isinstance(data, dict):
        return {k: rounded(v, resolution.get(str(k), digits), resolution) for k, v in data.items()}
    if isinstance(data, (list, tuple)):
        return [rounded(v, digits, resolution) for v in data]
    if hasattr(data, "tolist"):
        return rounded(data.tolist(), digits, resolution)
    return data


def unix_stamped(data: dict[str, Any], key: str = "t") -> dict[str, Any]:
    """``data`` with its ``time.monotonic()`` reading ``key`` given as Unix time (s), the one
    time base of every ``--json`` output, and the monotonic reading kept as ``t_mono``."""
    import time

    out: dict[str, Any] = {}
    for k, v in data.items():
        if k == key and isinstance(v, (int, float)):
            out[k] = v + time.time() - time.monotonic()
            out["t_mono"] = v
        else:
            out[k] = v
    return out


def print_json(data: Any) -> None:
    """``data`` as one line of JSON on stdout (``--json`` is JSON Lines everywhere, ``--once``
    included; round floats first with :func:`rounded`)."""
    typer.echo(json.dumps(data, default=_json_default, allow_nan=True))


def print_json_line(data: Any) -> None:
    """One compact JSON object on one line (JSON Lines), flushed: for pipes and scripts."""
    sys.stdout.write(json.dumps(data, default=_json_default) + "\n")
    sys.stdout.flush()


def _json_default(obj: Any) -> Any:
    if hasattr(obj, "tolist"):
        return obj.tolist()
    if isinstance(obj, (set, frozenset, tuple)):
        return list(obj)
    return str(obj)
