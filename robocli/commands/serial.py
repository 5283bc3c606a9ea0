"""``robocli serial``: write to and read from a serial port on the hub's computer, a thin
layer over :meth:`robocli.devices.hub.client.Hub.serial` (ros4mat SERIAL_CMD)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import typer

from robocli.commands._common import PlainCommand, from_env
from robocli.commands.hub import TokenOpt, open_hub
from robocli.defaults import HUB_ENV

SERIAL_MAX_WAIT_S = 5.0  #: the hub's longest serial read wait (MAX_SERIAL_WAIT_S)


class SerialCommand(PlainCommand):
    """``serial [HUB] PORT``: PORT is needed; HUB may be left out for ``$ROBOCLI_HUB``."""

    def collect_usage_pieces(self, ctx: Any) -> list[str]:
        return [p.replace("[PORT]", "PORT") for p in super().collect_usage_pieces(ctx)]


def serial(
    ctx: typer.Context,
    hub: str = typer.Argument(
        ..., help=f"Hub address HOST[:PORT]; leave it out to use ${HUB_ENV}.", metavar="[URL]",
        show_default=False, envvar=HUB_ENV, show_envvar=True,
    ),  # fmt: skip
    port: str | None = typer.Argument(  # noqa: UP007
        None, help="The serial port on the hub, e.g. /dev/ttyUSB0.", metavar="PORT",
        show_default=False,
    ),  # fmt: skip
    baud: int = typer.Option(9600, "--baud", min=50, help="Baud rate."),
    send: str = typer.Option("", "--send", help="Bytes to send: text, or hex with --hex."),
    recv: int = typer.Option(0, "--recv", min=0, max=1024, help="Bytes to read back."),
    hex_io: bool = typer.Option(False, "--hex", help="--send is hex; print the reply in hex."),
    timeout: float = typer.Option(  # at most robocli.hub.sources.real.MAX_SERIAL_WAIT_S
        1.0,
        "--timeout",
        min=0,
        max=SERIAL_MAX_WAIT_S,
        help="Read timeout, s (the hub waits at most 5 s, ros4mat's receive timeout).",
    ),  # fmt: skip
    parity: bool = typer.Option(False, "--parity", help="Even parity."),
    stop_bits: int = typer.Option(1, "--stop-bits", min=1, max=2, help="Stop bits."),
    token_file: Path | None = TokenOpt,  # noqa: UP007
) -> None:
    """Write to and read from a serial port on the hub (ros4mat SERIAL_CMD)."""
    if port is None:  # one word: PORT, on the hub of $ROBOCLI_HUB
        default = os.environ.get(HUB_ENV, "").strip()
        if not default or from_env(ctx, "hub"):
            raise typer.BadParameter(f"give HUB PORT, or PORT alone with ${HUB_ENV} set")
        hub, port = default, hub
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
