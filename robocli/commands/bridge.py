"""``robocli bridge pioneer|arm``: put a robot on Eclipse Zenoh (thin layers over
:mod:`robocli.bridge`). The other side, ``connect|teleop pioneer zenoh/<robot>``, is in
:mod:`robocli.commands.remote`."""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any

import typer

from robocli.commands import _zenoh
from robocli.commands._arm import LINK, ArmLink, HostArg, arm_link
from robocli.commands._arm import connected as connected_arm
from robocli.commands._common import sigterm_as_interrupt
from robocli.commands.pioneer import BaudOpt, PortArg, SubtypeOpt, TimeoutOpt, connected
from robocli.views.pioneer import start_laser

NameOpt = typer.Option(None, "--name", metavar="NAME",
                       help="The robot's name on Zenoh (default: the --zenoh configuration's "
                       "user, else pioneer or arm).")  # fmt: skip
SilenceOpt = typer.Option(0.5, "--silence", min=0.05, max=60.0, metavar="SECONDS", help="Stop a "
                         "moving robot when its controller sends nothing for this long.")


def pioneer(
    port: str = PortArg,
    zenoh: str = _zenoh.zenoh_option("server", default="tcp/127.0.0.1:7447"),
    name: str | None = NameOpt,
    silence: float = SilenceOpt,
    subtype: str | None = SubtypeOpt,
    baud: int = BaudOpt,
    timeout: float = TimeoutOpt,
    ros2: bool = _zenoh.Ros2Opt,
    ros2_domain: int = _zenoh.Ros2DomainOpt,
    ros2_namespace: str = _zenoh.Ros2NamespaceOpt,
) -> None:
    """Put a Pioneer on Zenoh: its state for any number of watchers, velocity from one
    controller at a time, until Ctrl-C. The robot stops when its controller's commands stop
    for --silence, when the controller goes, and when the bridge ends."""
    from robocli.bridge.pioneer import PioneerBridge

    robot_name = _checked(name, zenoh, "pioneer", ros2)
    with connected(port, subtype=subtype, baudrate=baud, timeout=timeout) as robot:
        start_laser(robot, wait=False)
        said = f"bridge {robot_name}: pioneer {robot.params.subtype} on {robot.transport.url}"
        _run(lambda session: PioneerBridge(robot, session, robot_name, silence=silence), said,
             zenoh, ros2, ros2_domain, ros2_namespace)  # fmt: skip


@arm_link()
def arm(
    host: str = HostArg,
    zenoh: str = _zenoh.zenoh_option("server", default="tcp/127.0.0.1:7447"),
    name: str | None = NameOpt,
    link: ArmLink = LINK,
    ros2: bool = _zenoh.Ros2Opt,
    ros2_domain: int = _zenoh.Ros2DomainOpt,
    ros2_namespace: str = _zenoh.Ros2NamespaceOpt,
) -> None:
    """Put an arm on Zenoh: joints, TCP pose and status for any number of watchers,
    trajectory uploads from one controller at a time, until Ctrl-C. A running trajectory is
    stopped when its controller goes and when the bridge ends."""
    from robocli.bridge.arm import ArmBridge

    robot_name = _checked(name, zenoh, "arm", ros2)
    with connected_arm(host, link) as robot:
        robot.wait_for_state()
        said = f"bridge {robot_name}: arm {robot.robot.name}"
        _run(lambda session: ArmBridge(robot, session, robot_name), said, zenoh, ros2,
             ros2_domain, ros2_namespace)  # fmt: skip


def _checked(name: str | None, zenoh: str, fallback: str, ros2: bool) -> str:
    """The robot's name on Zenoh (:func:`~robocli.commands._zenoh.server_name`), once
    ``--zenoh`` and ``--ros2`` are checked: before the robot is connected."""
    robot_name = _zenoh.server_name(name, zenoh, fallback)
    _zenoh.zenoh_target(zenoh)
    _zenoh.ros2_check(ros2, zenoh)
    return robot_name


def _run(make: Callable[[Any], Any], said: str, zenoh: str, ros2: bool, domain: int,
         namespace: str) -> None:  # fmt: skip
    """The bridge ``make(session)`` on the ``--zenoh`` session (and a ROS 2 node with
    ``ros2``), saying where, until Ctrl-C or its failure (raised)."""
    from robocli.bridge.ros2 import ros2_node
    from robocli.zenoh.session import close_session

    target = _zenoh.zenoh_target(zenoh)
    session = _zenoh.zenoh_session(zenoh, "server")
    try:
        with sigterm_as_interrupt(), make(session) as bridge:
            with ros2_node(bridge, session, ros2, domain=domain, namespace=namespace) as ros:
                typer.echo(f"{said}, Zenoh {target}" + (f", ROS 2 domain {domain}" if ros else ""))
                sys.stdout.flush()
                while not bridge.wait(0.5):
                    pass
            if bridge.failure is not None:
                raise bridge.failure
    finally:
        close_session(session)
