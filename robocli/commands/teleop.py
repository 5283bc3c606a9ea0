"""``robocli teleop pioneer|arm``: drive a robot from the keyboard, thin layers over
:mod:`robocli.devices.pioneer.teleop` and :mod:`robocli.devices.arm.teleop`.

Both read keys in cbreak mode (Ctrl-C still interrupts), redraw a status line in place at
10 Hz, and stop the robot when the keys stop coming (``--release``), on q, Ctrl-C or SIGTERM.
"""

from __future__ import annotations

import sys
import time
from typing import TYPE_CHECKING, Any

import typer

from robocli.commands import pioneer as pioneer_cli
from robocli.commands._arm import LINK, ArmLink, HostArg, arm_link
from robocli.commands._arm import connected as connected_arm
from robocli.commands._options import StreamOpt

if TYPE_CHECKING:
    pass

RELEASE_HELP = "Stop this long after the last key, s."


def _limit(default: float, flag: str, most: float, help: str, least: float = 0.0,
           **more: Any) -> Any:  # fmt: skip
    """A speed or time option from ``least`` to ``most``."""
    return typer.Option(default, flag, min=least, max=most, help=help, **more)


def pioneer(
    port: str = pioneer_cli.PortArg,
    max_v: float = _limit(0.4, "--max-v", 2.0, "Top speed, m/s.", metavar="M/S"),
    max_w: float = _limit(1.0, "--max-w", 5.0, "Top turn rate, rad/s (shown in deg/s).",
                          metavar="RAD/S"),  # fmt: skip
    release: float = _limit(0.45, "--release", 0.5, RELEASE_HELP, 0.05, metavar="SECONDS"),
    subtype: str | None = pioneer_cli.SubtypeOpt,
    baud: int = pioneer_cli.BaudOpt,
    timeout: float = pioneer_cli.TimeoutOpt,
    zenoh: str | None = pioneer_cli.ZenohClientOpt,
) -> None:
    """Drive with the arrow keys or WASD; space stops, q quits. Letting go stops the robot.
    PORT zenoh/ROBOT: a robot behind a bridge (robocli bridge pioneer), with --zenoh."""
    from robocli.commands._screens import StatusLine, keys
    from robocli.commands.remote import is_remote, teleop_remote
    from robocli.devices.pioneer.teleop import TeleopController, run_teleop

    remote = is_remote(port, zenoh)
    _need_terminal()
    controller = TeleopController(max_v=max_v, max_w=max_w, release_timeout=release)
    if remote:
        teleop_remote(port, zenoh, controller, timeout)
        return
    with pioneer_cli.connected(port, subtype=subtype, baudrate=baud, timeout=timeout) as robot:
        robot.enable_motors()
        typer.echo(
            f"{robot.identity.name} ({robot.params.subtype}): arrows/WASD drive, "
            "space stops, q or Ctrl-C quits"
        )
        status = StatusLine(robot)
        with keys() as read_key:
            run_teleop(robot, status.reader(read_key), controller, on_update=status.command)


@arm_link()
def arm(
    host: str = HostArg,
    stream: bool = StreamOpt,
    joint_speed: float = _limit(0.1, "--joint-speed", 1.0, "Fraction of the joint speed limits.",
                                0.01),  # fmt: skip
    cart_speed: float = _limit(0.05, "--cart-speed", 1.0, "TCP speed, m/s.", 0.001),
    release: float = _limit(0.45, "--release", 1.0, RELEASE_HELP, 0.05),
    stale: float = _limit(1.0, "--stale", 60.0, "Stop when no joint state came this long, s.", 0.1),
    link: ArmLink = LINK,
) -> None:
    """Jog a joint (1-6, arrows/WASD) or the TCP (c; arrows/WASD in x and y, r/f in z);
    +/- speed, space stops, q quits. Letting go of the key sends STOP."""
    from robocli.commands._screens import keys
    from robocli.devices.arm.teleop import ArmTeleop, run_arm_teleop

    _need_terminal()
    with connected_arm(host, link, stream) as arm:
        arm.wait_for_state()
        typer.echo(f"{arm.robot.name} ({'streaming' if stream else 'ABB download'}): "
                   "1-6 joint, c TCP, arrows/WASD jog (r/f: z)")  # fmt: skip
        typer.echo("+/- speed, space stops, q or Ctrl-C quits")  # 80 columns each
        jog = ArmTeleop(arm, stream=stream, joint_speed=joint_speed, cart_speed=cart_speed,
                        release_timeout=release, stale=stale)  # fmt: skip
        with keys() as read_key:
            run_arm_teleop(jog, read_key, on_update=_status_line())


def _need_terminal() -> None:
    """A usage error unless keys can come from a terminal (checked before connecting)."""
    if not sys.stdin.isatty():
        raise typer.BadParameter("teleop needs an interactive terminal on standard input")


def _status_line() -> Any:
    """``on_update`` that redraws the arm teleop's status in place at 10 Hz."""
    from robocli.commands._screens import STATUS_PERIOD

    last = [-1.0]

    def draw(jog: Any) -> None:
        now = time.monotonic()
        if now - last[0] >= STATUS_PERIOD:
            last[0] = now
            sys.stdout.write("\r" + jog.status()[:79] + "\x1b[K")
            sys.stdout.flush()

    return draw
