"""``robocli ports``: the serial ports of this computer, with what is plugged into them."""

from __future__ import annotations

import typer

from robocli.commands._common import print_json
from robocli.commands._options import json_option


def ports(
    json_out: bool = json_option("One line: a JSON list of the ports."),
) -> None:
    """List serial ports (a Pioneer's USB-serial adapter shows as /dev/ttyUSB0, COM3...)."""
    from robocli.transports import list_serial_ports

    found = list_serial_ports()
    if json_out:
        print_json(found)
        return
    if not found:
        typer.echo("no serial ports found (is the USB-serial adapter plugged in?)")
        return
    width = max(len("DEVICE"), *(len(p["device"]) for p in found))
    described = max(len("DESCRIPTION"), *(len(p["description"]) for p in found))
    typer.echo(f"{'DEVICE':<{width}}  {'DESCRIPTION':<{described}}  HWID")
    for p in found:
        typer.echo(f"{p['device']:<{width}}  {p['description']:<{described}}  {p['hwid']}")
