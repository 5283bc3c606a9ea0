"""``robocli bridge pioneer|arm``: put a robot on Eclipse Zenoh (thin layers over
:mod:`robocli.bridge`). The other side, ``connect|teleop pioneer zenoh/<robot>``, is in
:mod:`robocli.commands.remote`."""

from __future__ import annotations

import sys

import typer

from robocli.commands import _zenoh
from robocli.commands._arm import LINK, ArmLink, HostArg, arm_link
from robocli.commands._arm import connected as connected_arm
from robocli.commands._common import sigterm_as_interrupt
from robocli.commands.pioneer import (
    BaudOpt,
    PortArg,
    SubtypeOpt,
    TimeoutOpt,
    connected,
    start_laser,
)

NameOpt = typer.Option(None, "--name", metavar="NAME",
                       help="The robot's name on Zenoh (default: the --zenoh configuration's "
                       "user, else pioneer or arm).")  # fmt: skip
SilenceOpt = typer.Option(
    0.5, "--silence", min=0.05, max=60.0, metavar="SECONDS",
    help="Stop a moving robot when its controller sends nothing for this long.",
)  # fmt: skip


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
    from robocli.bridge.ros2 import ros2_node
    from robocli.zenoh.session import close_session

    robot_name = _zenoh.server_name(name, zenoh, "pioneer")
    target = _zenoh.zenoh_target(zenoh)
    _zenoh.ros2_check(ros2, zenoh)
    with connected(port, subtype=subtype, baudrate=baud, timeout=timeout) as robot:
        start_laser(robot, wait=False)
        session = _zenoh.zenoh_session(zenoh, "server")
        try:
            with sigterm_as_interrupt(), PioneerBridge(robot, session, robot_name,
                                                       silence=silence) as bridge:  # fmt: skip
                with ros2_node(bridge, session, ros2, domain=ros2_domain,
                               namespace=ros2_namespace) as ros:  # fmt: skip
                    typer.echo(f"bridge {robot_name}: pioneer {robot.params.subtype} on "
                               f"{robot.transport.url}, Zenoh {target}"
                               + (f", ROS 2 domain {ros2_domain}" if ros else ""))  # fmt: skip
                    sys.stdout.flush()
                    while not bridge.wait(0.5):
                        pass
                if bridge.failure is not None:
                    raise bridge.failure
        finally:
            close_session(session)


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
    from robocli.bridge.ros2 import ros2_node
    from robocli.zenoh.session import close_session

    robot_name = _zenoh.server_name(name, zenoh, "arm")
    target = _zenoh.zenoh_target(zenoh)
    _zenoh.ros2_check(ros2, zenoh)
    with connected_arm(host, link) as robot:
        robot.wait_for_state()
        session = _zenoh.zenoh_session(zenoh, "server")
        try:
            with sigterm_as_interrupt(), ArmBridge(robot, session, robot_name) as bridge:
                with ros2_node(bridge, session, ros2, domain=ros2_domain,
                               namespace=ros2_namespace) as ros:  # fmt: skip
                    typer.echo(f"bridge {robot_name}: arm {robot.robot.name}, Zenoh {target}"
                               + (f", ROS 2 domain {ros2_domain}" if ros else ""))  # fmt: skip
                    sys.stdout.flush()
                    while not bridge.wait(0.5):
                        pass
                if bridge.failure is not None:
                    raise bridge.failure
        finally:
            close_session(session)
