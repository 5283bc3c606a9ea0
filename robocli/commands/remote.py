"""``connect pioneer`` and ``teleop pioneer`` with PORT ``zenoh/<robot>``: a Pioneer
through a bridge on Zenoh (``robocli bridge pioneer``), over
:class:`robocli.bridge.RemotePioneer`."""

from __future__ import annotations

from typing import Any

import typer

from robocli.commands._common import sigterm_as_interrupt
from robocli.commands._zenoh import zenoh_target

#: PORT of ``connect pioneer`` and ``teleop pioneer`` that names a robot behind a bridge
ZENOH_PREFIX = "zenoh/"


def remote(port: str, zenoh: str | None, timeout: float, **options: Any) -> Any:
    """The :class:`~robocli.bridge.RemotePioneer` of PORT ``zenoh/<robot>`` (its endpoint
    in the URL, ``?zenoh=``, or given by ``--zenoh``: once)."""
    from robocli.bridge import RemotePioneer

    target = None if zenoh is None else zenoh_target(zenoh)
    return RemotePioneer.connect(port, target, timeout=timeout, **options)


def is_remote(port: str, zenoh: str | None) -> bool:
    """PORT names a robot behind a bridge (``zenoh/<robot>``); ``--zenoh`` with any other
    PORT is a usage error."""
    if port.startswith(ZENOH_PREFIX):
        return True
    if zenoh is not None:
        raise typer.BadParameter(
            f"--zenoh reaches a robot through a bridge: give PORT zenoh/ROBOT, not {port!r}"
        )
    return False


def connect_remote(port: str, zenoh: str | None, once: bool, json_out: bool,
                   timeout: float) -> None:  # fmt: skip
    """``connect pioneer zenoh/<robot>``: the state the bridge puts, one snapshot (--once)
    or one line (JSON Lines with --json) per state until Ctrl-C."""
    from robocli.commands._common import print_json, reader_may_leave, rounded
    from robocli.commands._screens import state_line

    with reader_may_leave(), sigterm_as_interrupt(), remote(port, zenoh, timeout) as robot:
        if once:
            if json_out:
                print_json(rounded(_snapshot(robot)))
            else:
                typer.echo(f"{robot.robot} ({robot.info.get('subtype')}) through Zenoh, held "
                           f"by {robot.info.get('holder') or 'nobody'}")  # fmt: skip
                typer.echo(state_line(robot.state))
            return
        while True:
            state = robot.wait_for_state()
            if json_out:
                print_json(rounded(_snapshot(robot)))
            else:
                print(state_line(state), flush=True)


def teleop_remote(port: str, zenoh: str | None, controller: Any, timeout: float) -> None:
    """``teleop pioneer zenoh/<robot>``: drive through the bridge (refused, exit 4, while
    another controller holds the robot)."""
    from robocli.commands._screens import StatusLine, keys
    from robocli.devices.pioneer.teleop import run_teleop

    with sigterm_as_interrupt(), remote(port, zenoh, timeout) as robot:
        robot.acquire()
        robot.state  # noqa: B018 - the first state, or TimeoutError before the terminal mode
        typer.echo(f"{robot.robot} through Zenoh as {robot.holder}: arrows/WASD drive, "
                   "space stops, q or Ctrl-C quits")  # fmt: skip
        status = StatusLine(robot)  # reads pose and battery only
        with keys() as read_key:
            run_teleop(robot, status.reader(read_key), controller, on_update=status.command)


def _snapshot(robot: Any) -> dict[str, Any]:
    from robocli.bridge.pioneer import state_json

    state = robot.state
    return {"robot": robot.robot, "info": robot.info,
            "state": state_json(state, len(state.sonar), robot.offset)}  # fmt: skip
