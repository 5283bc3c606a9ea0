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

from robocli.commands._common import bind_address, listening, sigterm_as_interrupt
from robocli.commands._live import FoxgloveHostOpt, FoxgloveOpt, hub_live_view
from robocli.commands._replay import LoopOpt, ReplayOpt, SpeedOpt, check_replay
from robocli.commands._zenoh import (
    Ros2DomainOpt,
    Ros2NamespaceOpt,
    Ros2Opt,
    ros2_check,
    server_name,
    zenoh_option,
    zenoh_session,
)

if TYPE_CHECKING:
    from robocli.hub_server import HubServer, tune_hub_process

    tune_hub_process()
STATUS_PERIOD_S = 0.5
ZENOH_PUBLISH = "adc,imu,gps,battery,sysinfo"
"""What ``serve --zenoh`` publishes from the start, at each sensor's default settings."""


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
    sim: bool = typer.Option(False, "--sim", help="Serve every simulated sensor."),
    port: int = typer.Option(1500, "--port", "-p", min=0, max=65535, help="TCP port (0: any)."),
    bind: str = typer.Option(
        "127.0.0.1", "--bind", help="Address to listen on (0.0.0.0 exposes the hub: warned)."
    ),
    pioneer: str | None = typer.Option(
        None,
        "--pioneer",
        metavar="URL",
        help="A Pioneer (or 'robocli sim pioneer') for the battery and ADC.",
    ),
    laser: str | None = typer.Option(
        None,
        "--laser",
        metavar="URL",
        help="A Hokuyo laser (or 'robocli sim laser') for the laser sensor (HOKUYO).",
    ),
    gpsd: str | None = typer.Option(
        None, "--gpsd", metavar="HOST[:PORT]", help="Take the GPS from this gpsd daemon."
    ),
    serial: list[str] = typer.Option(
        [], "--serial", metavar="PORT", help="A serial port clients may use (repeatable)."
    ),
    token_file: Path | None = typer.Option(
        None,
        "--token-file",
        dir_okay=False,
        metavar="FILE",
        help="Require this file's token to change settings or write to a serial port.",
    ),
    max_clients: int = typer.Option(64, "--max-clients", min=1, max=4096, help="Connections."),
    foxglove: int | None = FoxgloveOpt,
    foxglove_host: str = FoxgloveHostOpt,
    replay: Path | None = ReplayOpt,
    speed: float | None = SpeedOpt,
    loop: bool = LoopOpt,
    zenoh: str | None = zenoh_option("server"),
    name: str | None = typer.Option(
        None,
        "--name",
        help="The hub's name on Zenoh (default: the --zenoh configuration's user, else this "
        "host's name).",
    ),
    publish: str = typer.Option(
        ZENOH_PUBLISH,
        "--publish",
        metavar="SENSOR[=RATE],...",
        help="Sensors published on Zenoh from the start (others once a client asks).",
    ),
    tcp: bool = typer.Option(True, "--tcp/--no-tcp", help="Serve ros4mat on TCP (--port)."),
    ros2: bool = Ros2Opt,
    ros2_domain: int = Ros2DomainOpt,
    ros2_namespace: str = Ros2NamespaceOpt,
) -> None:
    """Run the sensor hub, wire-compatible with ros4mat v3, until Ctrl-C. With --zenoh,
    also publish its sensors on robocli/NAME/SENSOR (--no-tcp: on Zenoh only)."""
    from robocli.hub_server import HubServer, tune_hub_process

    if not tcp and zenoh is None:
        raise typer.BadParameter("--no-tcp serves nothing without --zenoh")
    ros2_check(ros2, zenoh)
    sources = replay_sources(replay, speed, loop)
    tune_hub_process()
    token = token_from_file(token_file)
    sources = sources or {}
    if laser:
        from robocli.hub_server.sources.hokuyo import HokuyoSource

        sources["laser"] = HokuyoSource(laser)
    srv = HubServer(
        bind_address(bind), port, sim=sim, serial_ports=tuple(serial), gpsd=gpsd, pioneer=pioneer,
        token=token, max_clients=max_clients, sources=sources,
    )  # fmt: skip
    frontend: Any = None
    ros: Any = None
    with sigterm_as_interrupt():  # Ctrl-C, SIGTERM: every connection closes, exit 130
        try:
            if tcp:
                with listening(bind):
                    srv.start()
            if zenoh is not None:
                frontend = _zenoh_frontend(srv, zenoh, name, publish, token)
                if ros2:
                    from robocli.hub_server.frontends.ros2 import HubTopics

                    ros = HubTopics(srv.hub, frontend.session, frontend.name,
                                    domain=ros2_domain, namespace=ros2_namespace)  # fmt: skip
                    frontend.on_batch = ros.batch
            for warning in srv.warnings:
                typer.secho(f"WARNING: {warning}", err=True, fg="red", bold=True)
            for note in _replaced(sim, pioneer, gpsd, laser):
                typer.echo(note, err=True)
            what = f"hub replaying {replay}: " if replay is not None else "hub "
            where = [srv.url] if tcp else []
            if frontend is not None:
                where.append(f"zenoh robocli/{frontend.name}/* ({zenoh})")
            if ros is not None:
                where.append(f"ROS 2 domain {ros2_domain}")
            served = [*srv.sensors, *(f"serial port {p}" for p in srv.serial_ports)]
            typer.echo(f"{what}serving {', '.join(served)} on {' and '.join(where)}")
            sys.stdout.flush()
            with hub_live_view(foxglove, foxglove_host, srv, token):  # what clients make it run
                if sys.stdout.isatty():
                    _live(srv)
                else:
                    _log(srv)
        finally:
            if frontend is not None:
                from robocli.zenoh.session import close_session

                frontend.close()
                if ros is not None:
                    ros.close()
                close_session(frontend.session)
            srv.close()


def replay_sources(replay: Path | None, speed: float | None, loop: bool) -> Any:
    """``--replay``'s sources (None without it)."""
    rate = check_replay(replay, speed, loop)
    if replay is None:
        return None
    from robocli.hub_server.sources.replay import replay_sources as sources_of

    return sources_of(replay, rate, loop)


def _zenoh_frontend(
    srv: HubServer, zenoh: str, name: str | None, publish: str, token: bytes | None
) -> Any:
    """The hub's Zenoh front-end, started (its session listening on ``zenoh``)."""
    from robocli.hub_server.frontends.zenoh import ZenohFrontend
    from robocli.zenoh.keys import default_name
    from robocli.zenoh.session import close_session

    hub_name = server_name(name, zenoh, default_name())
    sensors = _published(publish, srv)
    session = zenoh_session(zenoh, "server")
    try:
        return ZenohFrontend(srv.hub, session, hub_name, token=token, publish=sensors,
                             serial=srv.serial).start()  # fmt: skip
    except BaseException:
        close_session(session)
        raise


def _published(text: str, srv: HubServer) -> dict[str, dict[str, Any] | None]:
    """``--publish``: sensor -> its settings (None: defaults); sensors this hub does not
    have are left out of the default list, refused when named."""
    from robocli.devices.hub.over_zenoh import hub_name_of
    from robocli.devices.hub.subscription import subscribe_request
    from robocli.errors import InvalidArgument

    out: dict[str, dict[str, Any] | None] = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        sensor, _, rate = item.partition("=")
        try:
            hub_sensor = hub_name_of(sensor.strip())
            params = subscribe_request(sensor.strip(), float(rate))["params"] if rate else None
        except (InvalidArgument, ValueError) as exc:
            raise typer.BadParameter(f"{item!r}: {exc}", param_hint="'--publish'") from None
        if hub_sensor in srv.hub.channels:
            out[hub_sensor] = params
        elif text != ZENOH_PUBLISH:
            raise typer.BadParameter(f"this hub has no {hub_sensor}", param_hint="'--publish'")
    return out


def _replaced(
    sim: bool, pioneer: str | None, gpsd: str | None, laser: str | None = None
) -> list[str]:
    """What replaces simulated sensors when real ones are given with ``--sim``."""
    if not sim:
        return []
    notes = []
    if pioneer:
        notes.append(f"adc and battery: from the Pioneer at {pioneer.strip()} (--pioneer "
                     "replaces the simulated ones)")  # fmt: skip
    if gpsd:
        notes.append(f"gps: from gpsd at {gpsd} (--gpsd replaces the simulated one)")
    if laser:
        notes.append(f"laser: from the Hokuyo at {laser.strip()} (--laser replaces the "
                     "simulated one)")  # fmt: skip
    return notes


def status_lines(srv: HubServer) -> list[str]:
    """One line per active sensor and per known client (what the log prints on change)."""
    lines = []
    for name, s in srv.sensors.items():
        if s["active"]:
            lines.append(f"sensor {name}: {s['rate']:g} Hz, {s['subscribers']} subscriber(s)")
    for c in srv.clients:
        state = "connected" if c.connected else "detached"
        subs = ", ".join(f"{n}[{b}]" for n, b in c.subscriptions.items()) or "nothing"
        lines.append(f"client {c.id} {c.peer} {state}: {subs}")
    return lines


def _log(srv: HubServer) -> None:
    """Plain lines: what changed, every :data:`STATUS_PERIOD_S`."""
    shown: set[str] = set()
    while True:
        lines = status_lines(srv)
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


def _live(srv: HubServer) -> None:
    from rich.live import Live

    with Live(_table(srv), refresh_per_second=4, transient=False) as live:
        while True:
            time.sleep(STATUS_PERIOD_S)
            live.update(_table(srv))
