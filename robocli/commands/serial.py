"""``robocli serial``: write to and read from a serial port on the hub's computer, a thin
layer over :meth:`robocli.devices.hub.client.Hub.serial` (ros4mat SERIAL_CMD), or with
``--pty`` a local pseudo-terminal relayed to it (:class:`robocli.devices.hub.relay.PtyRelay`,
robocli's serial stream)."""

from __future__ import annotations

import os
import sys
import threading
from pathlib import Path
from typing import Any

import typer

from robocli.commands._common import PlainCommand, from_env
from robocli.commands._options import baud_option, flag, timeout_option
from robocli.commands.hub import TokenOpt, open_hub
from robocli.defaults import HUB_ENV

SERIAL_MAX_WAIT_S = 5.0  #: the hub's longest serial read wait (MAX_SERIAL_WAIT_S)


class SerialCommand(PlainCommand):
    """``serial [HUB] PORT``: PORT is needed; HUB may be left out for ``$ROBOCLI_HUB``."""

    def collect_usage_pieces(self, ctx: Any) -> list[str]:
        return [p.replace("[PORT]", "PORT") for p in super().collect_usage_pieces(ctx)]


def serial(
    ctx: typer.Context,
    hub: str = typer.Argument(..., help=f"Hub address HOST[:PORT]; leave it out to use ${HUB_ENV}.",
                              metavar="[URL]", show_default=False, envvar=HUB_ENV,
                              show_envvar=True),  # fmt: skip
    port: str | None = typer.Argument(None, help="The serial port on the hub, e.g. /dev/ttyUSB0.",
                                      metavar="PORT", show_default=False),  # fmt: skip
    baud: int = baud_option(9600, "Baud rate.", 50, None),
    send: str = typer.Option("", "--send", help="Bytes to send: text, or hex with --hex."),
    recv: int = typer.Option(0, "--recv", min=0, max=1024, help="Bytes to read back."),
    hex_io: bool = flag("--hex", "--send is hex; print the reply in hex."),
    timeout: float = timeout_option(1.0, "Read timeout, s (the hub waits at most 5 s, ros4mat's "
                                    "receive timeout).", 0, SERIAL_MAX_WAIT_S),  # fmt: skip
    parity: bool = flag("--parity", "Even parity."),
    stop_bits: int = typer.Option(1, "--stop-bits", min=1, max=2, help="Stop bits."),
    token_file: Path | None = TokenOpt,
    pty: bool = flag("--pty", "Print the path of a local pty relayed to PORT until Ctrl-C."),
    zenoh: str | None = typer.Option(None, "--zenoh", metavar="CONFIG", help="With --pty: through "
                                     "the hub's Zenoh front-end, HUB being its name (the CONFIG "
                                     "file's user streams the port). Needs robocli-robots[zenoh]."),
) -> None:
    """Write to and read from a serial port on the hub (ros4mat SERIAL_CMD); with --pty, a
    local serial port (a pty) for any program, relayed both ways until Ctrl-C."""
    if port is None:  # one word: PORT, on the hub of $ROBOCLI_HUB
        default = os.environ.get(HUB_ENV, "").strip()
        if not default or from_env(ctx, "hub"):
            raise typer.BadParameter(f"give HUB PORT, or PORT alone with ${HUB_ENV} set")
        hub, port = default, hub
    if pty:
        if send or recv or hex_io:
            raise typer.BadParameter("--pty relays until Ctrl-C: no --send, --recv, --hex")
        _relay(hub, port, baud, token_file, zenoh)
        return
    if zenoh is not None:
        raise typer.BadParameter("--zenoh goes with --pty")
    if hex_io:
        try:
            data = bytes.fromhex(send)
        except ValueError:
            raise typer.BadParameter(f"--send: {send!r} is not hex") from None
    else:
        data = send.encode().decode("unicode_escape").encode("latin-1")
    with open_hub(hub, token_file=token_file, hub_option=False) as client:
        reply = client.serial(
            port, data, baud=baud, recv=recv, timeout=timeout, parity=parity,
            stop_bits=stop_bits,
        )  # fmt: skip
    typer.echo(reply.hex(" ") if hex_io else reply.decode("latin-1"))


def _relay(hub: str, port: str, baud: int, token_file: Path | None, zenoh: str | None) -> None:
    """The pty relay: its path on stdout, what happens to the hub on stderr (one line each)."""
    from robocli.commands._common import sigterm_as_interrupt
    from robocli.commands.serve import token_from_file
    from robocli.devices.hub.relay import PtyRelay

    def say(kind: str, text: str) -> None:
        if kind != "ended":  # the end is the error run() raises: main prints it
            typer.echo(f"robocli: {text}", err=True)

    token = token_from_file(token_file)
    with sigterm_as_interrupt(), PtyRelay(hub, port, baudrate=baud, token=token,
                                          on_event=say, zenoh=zenoh) as relay:  # fmt: skip
        typer.echo(relay.path)
        sys.stdout.flush()
        relay.run(threading.Event())
