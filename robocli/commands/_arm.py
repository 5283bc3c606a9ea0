"""How a command reaches an ABB (or any Simple Message) arm: its address (or ``sim``, an
embedded simulator), the link options every arm command takes (:func:`arm_link`), and the
connected :class:`~robocli.devices.arm.Arm` (:func:`connected`). Shared by ``upload``,
``monitor``, ``connect``, ``dump``, ``teleop``, ``bridge``, ``bench`` and ``record``."""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import typer

from robocli.commands._common import bundled, sigterm_as_interrupt
from robocli.commands._options import RobotOpt, device_argument
from robocli.defaults import ARM_ENV

if TYPE_CHECKING:
    from robocli.devices.arm import Arm

HostArg = device_argument("arm", ARM_ENV)
MotionPortOpt = typer.Option(11000, "--motion-port", min=1, max=65535, help="Motion port.")
StatePortOpt = typer.Option(11002, "--state-port", min=1, max=65535, help="State port.")
#: Choices of options (Literal: Typer checks them, lists them in -h and completes them).
ByteOrder = Literal["little", "big"]
RealSize = Literal[4, 8]
Profile = Literal["abb", "generic"]
Shape = Literal["circle", "rectangle"]
OrderOpt = typer.Option("little", "--byte-order", help="little (ABB) or big (Fanuc, FS100).")
RealOpt = typer.Option(4, "--real-size", help="Bytes per real: 4, or 8 (FLOAT64 builds).")
TimeoutOpt = typer.Option(5.0, "--timeout", min=0.1, max=600.0, help="Seconds per wait.")


def arm_host(*address: Any, **options: Any) -> Any:
    """:func:`robocli.devices.arm.jobs.arm_address` (loaded when called, not with the CLI)."""
    from robocli.devices.arm.jobs import arm_address

    return arm_address(*address, **options)


@dataclass(frozen=True)
class ArmLink:
    """How a command reaches the arm, as its link options gave it: the motion port (opened
    when ``motion``) and the state port, the wire format, the robot model, seconds per wait."""

    motion_port: int
    state_port: int
    byte_order: str
    real_size: int
    robot: str
    timeout: float
    motion: bool = True


#: Where a command takes the link options: ``link: ArmLink = LINK`` (see :func:`arm_link`).
LINK: Any = None
#: The link options, in the order -h lists them.
_LINK_OPTIONS = [
    ("motion_port", int, MotionPortOpt),
    ("state_port", int, StatePortOpt),
    ("byte_order", ByteOrder, OrderOpt),
    ("real_size", RealSize, RealOpt),
    ("robot", str, RobotOpt),
    ("timeout", float, TimeoutOpt),
]


def arm_link(motion: bool = True) -> Callable[[Callable[..., None]], Callable[..., None]]:
    """Give a command the arm's link options in place of its ``link: ArmLink = LINK``:
    --motion-port (not with ``motion`` false: the state port alone), --state-port,
    --byte-order, --real-size, --robot, --timeout; they reach it checked, as an
    :class:`ArmLink`."""
    return bundled("link", _LINK_OPTIONS, functools.partial(_link, motion))


def _link(motion: bool, motion_port: int = 11000, **wire: Any) -> ArmLink:
    """The options as an :class:`ArmLink` (``motion`` false: the motion port is not opened).
    The two ports must differ: one port cannot carry both links."""
    if motion_port == wire["state_port"]:
        from robocli.errors import InvalidArgument

        raise InvalidArgument(
            f"--motion-port and --state-port are both {motion_port}: the arm has two ports "
            "(ABB: 11000 and 11002)"
        )
    return ArmLink(motion_port, motion=motion, **wire)


@contextlib.contextmanager
def connected(host: str, link: ArmLink, stream: bool = False, **options: Any) -> Iterator[Arm]:
    """The arm at ``host`` (``sim``: an embedded simulator, the streaming one with
    ``stream``), SIGTERM stopping it as Ctrl-C does. ``options``: more of
    :meth:`Arm.connect`'s (``listeners``: a recorder's, from each port's first byte)."""
    with sigterm_as_interrupt(), arm_host(host, link.motion_port, link.state_port,
                                          link.byte_order, link.real_size, link.robot,
                                          "generic" if stream else "abb") as address:  # fmt: skip
        with connect_at(address, link, **options) as arm:
            yield arm


def connect_at(address: tuple[str, int, int], link: ArmLink, **options: Any) -> Arm:
    """:meth:`Arm.connect` to ``(host, motion_port, state_port)`` (from :func:`arm_host`)
    with ``link``'s options."""
    from robocli.devices.arm import Arm

    h, mp, sp = address
    return Arm.connect(h, mp, sp, motion=link.motion, byte_order=link.byte_order,
                       real_size=link.real_size, robot=link.robot, timeout=link.timeout,
                       **options)  # fmt: skip
