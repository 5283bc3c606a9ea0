"""``robocli connect|sim pioneer``, and what ``teleop pioneer`` and ``dump pioneer`` share
(the port argument and link options, connecting): thin layers over robocli.devices.pioneer.

Human views show metres, m/s, degrees and deg/s; JSON output is SI (m, rad, m/s, rad/s),
rounded to the protocol's resolution.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer

from robocli.commands import _common as common
from robocli.commands import _options as opt
from robocli.commands._live import FoxgloveHostOpt, FoxgloveOpt
from robocli.commands._replay import LoopOpt, ReplayOpt, SpeedOpt, check_replay
from robocli.commands._zenoh import zenoh_option
from robocli.defaults import PIONEER_ENV
from robocli.views.pioneer import snapshot, snapshot_lines
from robocli.views.pioneer import start_laser as start_laser

if TYPE_CHECKING:
    from robocli.devices.laser import MountedLaser, PlacedScan
    from robocli.devices.pioneer import Pioneer


def _check_subtype(value: str | None) -> str | None:
    """``--subtype`` must name a robot robocli has parameters for (a usage error, not the
    robot's fault)."""
    from robocli.robots.pioneer import ROBOT_PARAMS

    if value is not None and value not in ROBOT_PARAMS:
        raise typer.BadParameter(f"unknown subtype {value!r}; known: {', '.join(ROBOT_PARAMS)}")
    return value


PortArg = opt.device_argument("pioneer", PIONEER_ENV)
HOKUYO_HELP = (
    "A Hokuyo laser on the robot (placed as the robot model says): serial device, pyserial "
    "URL, tcp://host:10940, or 'sim' for a simulated one that moves with the robot."
)
GEOREF_HELP = "Map origin in degrees (and metres), for SIMSTAT's GPS fix."
SubtypeOpt = typer.Option(None, "--subtype", metavar="NAME", callback=_check_subtype,
                          help="Override the robot's subtype (p3dx, p3at, ...).")  # fmt: skip
BaudOpt = opt.baud_option(9600)
#: ``--zenoh`` of ``connect|teleop pioneer``: where to reach a bridge (PORT zenoh/<robot>)
ZenohClientOpt = zenoh_option("client")
TimeoutOpt = opt.timeout_option(5.0, "Seconds to wait for the robot: to connect, and for its next "
                                "SIP once connected.", 0.1, 3600.0, metavar="SECONDS")  # fmt: skip


@contextlib.contextmanager
def connected(port: str, **options: Any) -> Iterator[Pioneer]:
    """A connected Pioneer on ``port`` (``sim``: an embedded simulator), Ctrl-C and SIGTERM
    stopping it; a reset during the handshake is explained as a busy robot. ``--timeout``
    also bounds the wait once the robot goes silent."""
    from robocli.devices.pioneer import Pioneer

    options.setdefault("sip_timeout", options.get("timeout", 5.0))
    with common.reader_may_leave(), common.sigterm_as_interrupt():
        with common.explain_refusal(port):
            robot = Pioneer.connect(port, **options)
        with robot:
            yield robot


def connect(
    port: str = PortArg,
    once: bool = opt.flag("--once", "Print one state snapshot and exit."),
    json_out: bool = opt.json_option("JSON: one object with --once, else one line per SIP (JSON "
                                     "Lines)."),  # fmt: skip
    laser: str | None = opt.device_option("--laser", HOKUYO_HELP, show_default=False),
    no_laser: bool = opt.flag("--no-laser", "Do not start a simulator's own (ARCOS) laser."),
    subtype: str | None = SubtypeOpt,
    baud: int = BaudOpt,
    timeout: float = TimeoutOpt,
    foxglove: int | None = FoxgloveOpt,
    foxglove_host: str = FoxgloveHostOpt,
    zenoh: str | None = ZenohClientOpt,
) -> None:
    """Connect to a Pioneer and show its live state until q or Ctrl-C (--once: one
    snapshot; --json: machine-readable, SI units; --foxglove: also to Foxglove). PORT
    zenoh/ROBOT: a robot behind a bridge (robocli bridge pioneer), reached with --zenoh."""
    from robocli.commands._live import live_view as foxglove_view
    from robocli.commands._screens import live_view
    from robocli.commands.remote import connect_remote, is_remote

    if is_remote(port, zenoh):
        connect_remote(port, zenoh, once, json_out, timeout)
        return
    with foxglove_view(foxglove, foxglove_host) as view, \
            connected(port, subtype=subtype, baudrate=baud, timeout=timeout) as robot, \
            _hokuyo(laser, robot, once) as hokuyo:  # fmt: skip
        if view is not None:
            name = view.add(robot)
            if hokuyo is not None:  # its scans on the robot, as the robot model mounts it
                view.add(hokuyo.laser, parent=f"{name}/base_link", mount=hokuyo.mount)
        if not no_laser:
            start_laser(robot, wait=once)
        if once:
            placed = hokuyo.place(hokuyo.laser.scan()) if hokuyo is not None else None
            if json_out:
                common.print_json(common.rounded(_snapshot(robot, placed)))
            else:
                common.echo_lines(snapshot_lines(robot, placed))
        elif json_out:
            while True:  # like `ros2 topic echo`: one object per SIP until Ctrl-C
                latest = hokuyo.latest if hokuyo is not None else None
                common.print_json(common.rounded(_snapshot(robot, latest)))
                robot.wait_for_sip()
        else:
            live_view(robot, hokuyo)


def _snapshot(robot: Pioneer, hokuyo: PlacedScan | None = None) -> dict[str, Any]:
    """The robot's snapshot (:func:`robocli.views.pioneer.snapshot`), with the ``--laser``
    Hokuyo's placed scan."""
    from robocli.views.laser import placed_json

    return snapshot(robot, **({"hokuyo": placed_json(hokuyo)} if hokuyo is not None else {}))


@contextlib.contextmanager
def _hokuyo(url: str | None, robot: Pioneer, once: bool) -> Iterator[MountedLaser | None]:
    """The Hokuyo of ``--laser`` on ``robot`` (streaming unless ``once``), or None."""
    if url is None:
        yield None
        return
    from robocli.devices.laser import MountedLaser
    from robocli.devices.laser.mounted import on_robot

    with on_robot(url, robot) as laser:
        mounted = MountedLaser(laser, robot)
        try:
            if not once:
                laser.start()
            yield mounted
        finally:
            mounted.close()


def simulate(
    port: int = opt.port_option(8101, "First TCP port."),
    robots: int = typer.Option(1, "--robots", min=1, max=64, help="Robots on port, port+1..."),
    pty: bool = opt.flag("--pty", "Serve on a pseudo-terminal instead of TCP."),
    map_file: Path | None = opt.MapOpt,
    sip_ms: float = typer.Option(100.0, "--sip-ms", min=5.0, max=1000.0, help="SIP period, ms."),
    subtype: str = typer.Option("p3dx", "--subtype", help="Reported robot subtype."),
    bind: str = opt.BindOpt,
    time_scale: float = opt.TimeScaleOpt,
    laser: bool = opt.flag("--laser/--no-laser", "Simulate a SICK LMS200 (commands 35-38, "
                           "230-233).", True),  # fmt: skip
    georef: str | None = typer.Option(None, "--georef", metavar="LAT,LON[,ALT]", help=GEOREF_HELP),
    replay: Path | None = ReplayOpt,
    speed: float | None = SpeedOpt,
    loop: bool = LoopOpt,
) -> None:
    """Run simulated Pioneers speaking ARCOS (like MobileSim) until Ctrl-C."""
    from robocli.robots.pioneer import ROBOT_PARAMS
    from robocli.sim.launch import pioneers
    from robocli.sim.pioneer.server import PioneerSim
    from robocli.sim.world import World

    if subtype not in ROBOT_PARAMS:
        raise typer.BadParameter(f"unknown subtype {subtype!r}; known: {', '.join(ROBOT_PARAMS)}")
    rate = check_replay(replay, speed, loop)
    world = _load_map(World, map_file) if map_file else None
    sims: list[PioneerSim] = []
    with common.sigterm_as_interrupt():  # Ctrl-C, SIGTERM: the robots close, exit 130
        try:
            with common.listening(bind):
                sims = pioneers(robots, host=common.bind_address(bind), port=port, pty=pty,
                                world=world, laser=laser,
                                georef=_georef(georef) if georef else None,
                                replay=_recorded(replay), speed=rate, loop=loop, subtype=subtype,
                                sip_ms=sip_ms, time_scale=time_scale)  # fmt: skip
            what = f"replaying {replay}" if replay is not None else subtype
            for i, simulator in enumerate(sims):
                typer.echo(f"robot {i + 1}: {what} on {simulator.pty_path or simulator.url}")
            common.wait_forever()
        finally:
            for simulator in sims:
                simulator.close()


def _recorded(path: Path | None) -> Any:
    """The packets of the recording at ``path`` (None: no replay)."""
    from robocli.io.record.replay import RecordedPackets

    return None if path is None else RecordedPackets(path)


def _georef(text: str) -> tuple[float, float, float]:
    """``LAT,LON[,ALT]`` -> (lat, lon, alt); anything else is a usage error naming it."""
    parts = text.split(",")
    try:
        values = [float(v) for v in parts]
    except ValueError:
        values = []
    if (
        len(values) not in (2, 3)
        or not all(math.isfinite(v) for v in values)
        or abs(values[0]) > 90
        or abs(values[1]) > 180
    ):
        raise typer.BadParameter(
            f"{text!r} is not LAT,LON[,ALT] in degrees (and metres), e.g. 42.36,-71.06,10",
            param_hint="'--georef'",
        )
    lat, lon, *alt = values
    return lat, lon, alt[0] if alt else 0.0


def _load_map(world_type: Any, path: Path) -> Any:
    """``World.load(path)``; a file that is not UTF-8 text is a usage error naming it."""
    try:
        return world_type.load(path)
    except UnicodeDecodeError as exc:
        raise typer.BadParameter(
            f"{path} is not a map: not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at "
            f"offset {exc.start}); give JSON or text walls 'x1 y1 x2 y2'",
            param_hint="'--map'",
        ) from None
    except OSError as exc:
        raise typer.BadParameter(f"cannot read {path}: {exc.strerror or exc}") from None
