"""``robocli serve``: the sensor hub (ros4mat v3 on TCP 1500; with ``--zenoh``, also or
only on Eclipse Zenoh), a thin layer over :class:`robocli.hub_server.HubServer` and
:class:`robocli.hub_server.frontends.zenoh.ZenohFrontend`.

On a terminal: a live Rich table with a line per sensor and per client. Otherwise: plain
log lines, one per change (a client connects, subscribes, leaves), so that logs stay small.
Ctrl-C or SIGTERM closes every connection and stops every sensor.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer

from robocli.commands import _zenoh
from robocli.commands._common import bind_address, listening, sigterm_as_interrupt
from robocli.commands._live import FoxgloveHostOpt, FoxgloveOpt, hub_live_view
from robocli.commands._options import bind_option, device_option, flag, port_option
from robocli.commands._replay import LoopOpt, ReplayOpt, SpeedOpt, check_replay
from robocli.errors import InvalidArgument

if TYPE_CHECKING:
    from robocli.hub_server import HubServer
    from robocli.hub_server.service import HubService

STATUS_PERIOD_S = 0.5
#: What ``serve --zenoh`` publishes from the start (robocli.hub_server.service.ZENOH_PUBLISH).
ZENOH_PUBLISH = "adc,imu,gps,battery,sysinfo"


def token_from_file(path: Path | None) -> bytes | None:
    """The token in ``path`` (surrounding whitespace stripped: a trailing newline is not part
    of it), None for no path; a usage error when it cannot be read or is empty. The hub
    (``serve --token-file``) and its clients read token files alike."""
    if path is None:
        return None
    from robocli.devices.hub.client import MAX_TOKEN

    try:
        with path.open("rb") as f:  # bounded: a token is short, /dev/zero is not
            token = f.read(MAX_TOKEN + 64).strip()
    except OSError as exc:
        raise typer.BadParameter(f"cannot read {path}: {exc.strerror or exc}") from None
    if len(token) > MAX_TOKEN:
        raise typer.BadParameter(
            f"{path} holds more than a token ({MAX_TOKEN} bytes at most)",
            param_hint="'--token-file'",
        )
    if not token:
        raise typer.BadParameter(f"{path} is empty", param_hint="'--token-file'")
    return token


def serve(
    sim: bool = flag("--sim", "Serve every simulated sensor."),
    port: int = port_option(1500, "TCP port (0: any)."),
    bind: str = bind_option("Address to listen on (0.0.0.0 exposes the hub: warned)."),
    pioneer: str | None = device_option("--pioneer", "A Pioneer (or 'robocli sim pioneer') for "
                                        "the battery and ADC."),  # fmt: skip
    laser: str | None = device_option("--laser", "A Hokuyo laser (or 'robocli sim laser') for "
                                      "the laser sensor (HOKUYO)."),  # fmt: skip
    gpsd: str | None = typer.Option(None, "--gpsd", metavar="HOST[:PORT]",
                                    help="Take the GPS from this gpsd daemon."),  # fmt: skip
    serial: list[str] = typer.Option([], "--serial", metavar="PORT",
                                     help="A serial port clients may use (repeatable)."),
    token_file: Path | None = typer.Option(None, "--token-file", dir_okay=False, metavar="FILE",
                                           help="Require this file's token to change settings "
                                           "or write to a serial port."),  # fmt: skip
    max_clients: int = typer.Option(64, "--max-clients", min=1, max=4096, help="Connections."),
    foxglove: int | None = FoxgloveOpt,
    foxglove_host: str = FoxgloveHostOpt,
    replay: Path | None = ReplayOpt,
    speed: float | None = SpeedOpt,
    loop: bool = LoopOpt,
    zenoh: str | None = _zenoh.zenoh_option("server"),
    name: str | None = typer.Option(None, "--name", help="The hub's name on Zenoh (default: the "
                                    "--zenoh configuration's user, else this host's name)."),
    publish: str = typer.Option(ZENOH_PUBLISH, "--publish", metavar="SENSOR[=RATE],...",
                                help="Sensors published on Zenoh from the start (others once a "
                                "client asks)."),  # fmt: skip
    tcp: bool = flag("--tcp/--no-tcp", "Serve ros4mat on TCP (--port).", True),
    ros2: bool = _zenoh.Ros2Opt,
    ros2_domain: int = _zenoh.Ros2DomainOpt,
    ros2_namespace: str = _zenoh.Ros2NamespaceOpt,
) -> None:
    """Run the sensor hub, wire-compatible with ros4mat v3, until Ctrl-C. With --zenoh,
    also publish its sensors on robocli/NAME/SENSOR (--no-tcp: on Zenoh only)."""
    from robocli.hub_server import tune_hub_process
    from robocli.hub_server.service import HubService

    if not tcp and zenoh is None:
        raise typer.BadParameter("--no-tcp serves nothing without --zenoh")
    _zenoh.ros2_check(ros2, zenoh)
    rate = check_replay(replay, speed, loop)
    tune_hub_process()
    token = token_from_file(token_file)
    service = HubService(bind_address(bind), port, sim=sim, laser=laser, replay=replay, speed=rate,
                         loop=loop, serial_ports=tuple(serial), gpsd=gpsd, pioneer=pioneer,
                         token=token, max_clients=max_clients)  # fmt: skip
    with sigterm_as_interrupt(), service:  # Ctrl-C, SIGTERM: every connection closes, exit 130
        if tcp:
            with listening(bind):
                service.start_tcp()
        if zenoh is not None:
            from robocli.zenoh.keys import default_name

            hub_name = _zenoh.server_name(name, zenoh, default_name())
            try:
                sensors = service.published(publish)
            except InvalidArgument as exc:
                raise typer.BadParameter(str(exc), param_hint="'--publish'") from None
            ros = {"domain": ros2_domain, "namespace": ros2_namespace} if ros2 else None
            session = _zenoh.zenoh_session(zenoh, "server")
            service.start_zenoh(session, hub_name, sensors, ros, zenoh)
        for warning in service.server.warnings:
            typer.secho(f"WARNING: {warning}", err=True, fg="red", bold=True)
        for note in service.notes(pioneer, gpsd):
            typer.echo(note, err=True)
        typer.echo(service.served())
        sys.stdout.flush()
        with hub_live_view(foxglove, foxglove_host, service.server, token):  # what clients run
            (_live if sys.stdout.isatty() else _log)(service)


def _log(service: HubService) -> None:
    """Plain lines: what changed, every :data:`STATUS_PERIOD_S`."""
    shown: set[str] = set()
    while True:
        lines = service.status_lines()
        for line in lines:
            if line not in shown:
                typer.echo(line)
        for line in shown - set(lines):
            typer.echo(f"gone: {line}")
        sys.stdout.flush()
        shown = set(lines)
        time.sleep(STATUS_PERIOD_S)


def _table(srv: HubServer) -> Any:
    from rich.table import Table

    where = srv.url if srv.started else "zenoh"
    table = Table(title=f"robocli hub on {where}", expand=False)
    for col in ("what", "rate / peer", "subscribers / subscriptions", "pulls", "samples", "lost"):
        table.add_column(col)
    for name, s in srv.sensors.items():
        state = f"{s['rate']:g} Hz" if s["active"] else "idle"
        table.add_row(f"sensor {name}", state, str(s["subscribers"]), "", "", "")
    for c in srv.clients:
        subs = ", ".join(f"{n}[{b}]" for n, b in c.subscriptions.items()) or "-"
        who = c.peer if c.connected else f"{c.peer} (detached)"
        table.add_row(f"client {c.id}", who, subs, str(c.pulls), str(c.samples), str(c.dropped))
    return table


def _live(service: HubService) -> None:
    from rich.live import Live

    with Live(_table(service.server), refresh_per_second=4, transient=False) as live:
        while True:
            time.sleep(STATUS_PERIOD_S)
            live.update(_table(service.server))
