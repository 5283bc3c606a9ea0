"""``robocli router`` (a Zenoh router for a lab) and ``robocli list`` (the hubs and robots
that are up on Zenoh): thin layers over :mod:`robocli.zenoh`."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import typer

from robocli.commands._common import print_json, sigterm_as_interrupt
from robocli.commands._options import flag, json_option, timeout_option
from robocli.commands._zenoh import zenoh_option, zenoh_session, zenoh_target
from robocli.errors import EXIT_INTERRUPTED


def router(
    config: Path | None = typer.Option(None, "--config", dir_okay=False, metavar="FILE", help="A "
                                       "Zenoh JSON5 configuration (access control, TLS...); run "
                                       "in router mode."),  # fmt: skip
    listen: str | None = typer.Option(None, "--listen", "--zenoh", metavar="ENDPOINT", help="Listen"
                                      " on ENDPOINT (default tcp/127.0.0.1:7447; with --config: "
                                      "added to it)."),  # fmt: skip
    users: Path | None = typer.Option(None, "--users", dir_okay=False, metavar="FILE",
                                      help="Accept only clients with a user:password line of "
                                      "FILE (zenoh usrpwd)."),  # fmt: skip
    acl: bool = flag("--acl", "With --users: each user writes only under its own name (serves as "
                     "robocli/USER/..., commands robots as robocli/ROBOT/@control/USER/...); all "
                     "read."),  # fmt: skip
) -> None:
    """Run a Zenoh router until Ctrl-C: the lab server's, which robots and laptops connect
    to by endpoint (robocli serve/subscribe/list --zenoh CONFIG or ENDPOINT)."""
    from robocli.zenoh.router import start_router

    with sigterm_as_interrupt():
        try:
            target = zenoh_target(listen) if config is None else None
            running = start_router(target, config=config, listen=listen, users=users, acl=acl)
        except ValueError as exc:  # InvalidArgument: a bad file or endpoint
            raise typer.BadParameter(str(exc)) from None
        try:
            typer.echo(f"zenoh router {running.zid} listening on {', '.join(running.listen)}")
            sys.stdout.flush()
            while True:
                time.sleep(1.0)
        except KeyboardInterrupt:
            raise typer.Exit(EXIT_INTERRUPTED) from None
        finally:
            running.close()


def list_(
    zenoh: str | None = zenoh_option("client"),
    json_out: bool = json_option("One line: a JSON list of what is up."),
    timeout: float = timeout_option(2.0, "Wait for answers, s.", 0.1, 60),
) -> None:
    """List the hubs and robots that are up on Zenoh (their liveliness tokens), connecting
    to ENDPOINT (default tcp/127.0.0.1:7447) or as CONFIG."""
    from robocli.devices.hub.over_zenoh import alive
    from robocli.zenoh.session import close_session

    session = zenoh_session(zenoh, "client")
    try:
        up = alive(session, timeout)
    finally:
        close_session(session)
    if json_out:
        print_json([{"name": name, "kind": kind} for name, kind in up])
        return
    for name, kind in up:
        typer.echo(f"{kind:8} {name}")
    if not up:
        typer.echo("nothing is up", err=True)
