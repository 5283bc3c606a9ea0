"""``--foxglove PORT`` and ``--foxglove-host``: the live view of ``record``, ``connect
pioneer|arm|hub`` and ``serve`` (:class:`robocli.io.record.live.LiveView`)."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import TYPE_CHECKING

import typer

if TYPE_CHECKING:
    from robocli.hub_server import HubServer
    from robocli.io.record.live import LiveView

FoxgloveOpt = typer.Option(None, "--foxglove", min=0, max=65535, metavar="PORT", help="Serve "
                           "the channels live to Foxglove on this WebSocket port (8765 is "
                           "Foxglove's; 0: any). Needs pip install 'robocli-robots[foxglove]'.")
FoxgloveHostOpt = typer.Option("127.0.0.1", "--foxglove-host", metavar="HOST", help="Address the "
                               "live view listens on (0.0.0.0 exposes it).")  # fmt: skip


@contextlib.contextmanager
def live_view(port: int | None, host: str) -> Iterator[LiveView | None]:
    """A started live view on ``host:port`` (None without ``port``), its address said on
    stderr; stopped on the way out."""
    if port is None:
        yield None
        return
    from robocli.commands._common import bind_address
    from robocli.io.record.live import LiveView

    view = LiveView(bind_address(host), port)
    try:
        typer.echo(f"live view on {view.url} (Foxglove: Open connection > Foxglove WebSocket)",
                   err=True)  # fmt: skip
        yield view
    finally:
        view.close()


@contextlib.contextmanager
def hub_live_view(port: int | None, host: str, srv: HubServer,
                  token: bytes | None = None) -> Iterator[None]:  # fmt: skip
    """``serve --foxglove``: a client of the hub ``srv`` following every sensor it runs for
    its clients (:func:`~robocli.io.record.live.follow_hub`), served in a live view."""
    if port is None:
        yield
        return
    from robocli.hub_server.server import EXPOSED_BINDS
    from robocli.io.record.live import following_hub

    with live_view(port, host) as view:
        assert view is not None
        address = "127.0.0.1" if srv.bind in EXPOSED_BINDS else srv.bind
        with following_hub(view, address, srv.port, token):
            yield
