"""``robocli connect|teleop|dump|sim pioneer``: thin layers over robocli.devices.pioneer."""

from __future__ import annotations

import contextlib
import math
import os
import select
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer

from robocli.commands._common import (
    PORT_HELP,
    pioneer_url,
    print_json,
    sigterm_as_interrupt,
)

if TYPE_CHECKING:
    from rich.console import RenderableType

    from robocli.devices.pioneer import Pioneer

PortArg = typer.Argument(..., help=PORT_HELP, show_default=False)
SubtypeOpt = typer.Option(None, "--subtype", help="Override the robot's subtype (p3dx, ...).")
BaudOpt = typer.Option(9600, "--baud", min=300, help="Serial baud rate.")
TimeoutOpt = typer.Option(5.0, "--timeout", min=0.1, help="Seconds to wait for the robot.")


def connect(
    port: str = PortArg,
    once: bool = typer.Option(False, "--once", help="Print one state snapshot and exit."),
    json_out: bool = typer.Option(False, "--json", help="Machine-readable output (with --once)."),
    subtype: str | None = SubtypeOpt,  # noqa: UP007 - Typer needs Optional on 3.10
    baud: int = BaudOpt,
    timeout: float = TimeoutOpt,
) -> None:
    """Connect to a Pioneer, print its identity, then show its live state until Ctrl-C."""
    from robocli.devices.pioneer import Pioneer

    with sigterm_as_interrupt(), pioneer_url(port) as url:
        with Pioneer.connect(url, subtype=subtype, baud=baud, timeout=timeout) as robot:
            if once:
                snapshot = robot.snapshot()
                if json_out:
                    print_json(snapshot)
                else:
                    _print_snapshot(snapshot)
                return
            _live_view(robot)


def teleop(
    port: str = PortArg,
    max_v: float = typer.Option(0.4, "--max-v", min=0.0, max=2.0, help="Top speed, m/s."),
    max_w: float = typer.Option(1.0, "--max-w", min=0.0, max=5.0, help="Top turn rate, rad/s."),
    release: float = typer.Option(
        0.45, "--release", min=0.05, max=0.5, help="Stop this long after the last key, s."
    ),
    subtype: str | None = SubtypeOpt,  # noqa: UP007
    baud: int = BaudOpt,
    timeout: float = TimeoutOpt,
) -> None:
    """Drive with the arrow keys or WASD; space stops, q quits. Letting go stops the robot."""
    from robocli.devices.pioneer import Pioneer
    from robocli.devices.teleop import TeleopController, run_teleop

    if not sys.stdin.isatty():
        raise typer.BadParameter("teleop needs an interactive terminal on standard input")
    controller = TeleopController(max_v=max_v, max_w=max_w, release_timeout=release)
    with sigterm_as_interrupt(), pioneer_url(port) as url:
        with Pioneer.connect(url, subtype=subtype, baud=baud, timeout=timeout) as robot:
            robot.enable_motors()
            typer.echo(
                f"{robot.identity.name} ({robot.params.subtype}): arrows/WASD drive, "
                "space stops, q quits"
            )
            with _raw_terminal() as read_key:

                def show(v: float, w: float) -> None:
                    x, y, th = robot.pose
                    sys.stdout.write(
                        f"\rv {v:+.2f} m/s  w {w:+.2f} rad/s   pose {x:+7.2f} {y:+7.2f} "
                        f"{math.degrees(th):+6.1f} deg  battery {robot.battery:4.1f} V  "
                    )
                    sys.stdout.flush()

                run_teleop(robot, read_key, controller, on_update=show)
            typer.echo("")


def dump(
    port: str | None = typer.Argument(  # noqa: UP007
        None, help=PORT_HELP + " Omit with --file.", show_default=False
    ),
    count: int = typer.Option(0, "--count", "-n", min=0, help="Stop after N packets (0: none)."),
    hex_out: bool = typer.Option(False, "--hex", help="Also print the raw frame bytes."),
    file: Path | None = typer.Option(  # noqa: UP007
        None, "--file", "-f", help="Decode a capture (.jsonl trace or raw bytes) instead."
    ),
    subtype: str | None = SubtypeOpt,  # noqa: UP007
    baud: int = BaudOpt,
    timeout: float = TimeoutOpt,
) -> None:
    """Print every packet in both directions with its name and decoded fields."""
    from robocli.protocols import arcos

    if (port is None) == (file is None):
        raise typer.BadParameter("give either a PORT or --file, not both")
    printed = 0
    in_session = False

    def show(direction: str, payload: bytes, t: float | None) -> bool:
        nonlocal printed, in_session
        # direction of a raw capture is unknown: client commands never use SIP/CONFIG ids
        from_client = direction == "tx" or (direction == "?" and payload[0] < 0x20)
        name, fields = arcos.describe(payload, from_client=from_client, in_session=in_session)
        if (
            from_client
            and payload[0] == arcos.Command.OPEN
            and len(payload) > 1
            or (not from_client and payload[0] & 0xF0 == 0x30)
        ):
            in_session = True  # OPEN with its argument, or a SIP: the session has started
        arrow = {"tx": "->", "rx": "<-"}.get(direction, "  ")
        stamp = f"{t:10.6f} " if t is not None else ""
        text = " ".join(f"{k}={_short(v)}" for k, v in fields.items())
        typer.echo(f"{stamp}{arrow} {name:<13} {text}")
        if hex_out:
            frame = arcos.frame(payload)
            typer.echo(f"{'':{len(stamp)}}   {frame.hex(' ')}")
        printed += 1
        return bool(count) and printed >= count

    if file is not None:
        from robocli.io.capture import read_capture

        for item in read_capture(file):
            if show(item.direction, item.frame[3:-2], item.t):
                break
        return

    from robocli.devices.pioneer import Pioneer

    start = time.monotonic()
    done = False

    def listener(direction: str, payload: bytes, t: float) -> None:
        nonlocal done
        if not done:
            done = show(direction, payload, t - start)

    assert port is not None
    with sigterm_as_interrupt(), pioneer_url(port) as url:
        with Pioneer.connect(
            url, subtype=subtype, baud=baud, timeout=timeout, listeners=[listener]
        ) as robot:
            while not done:
                robot.wait_for_sip()


def simulate(
    port: int = typer.Option(8101, "--port", "-p", min=0, max=65535, help="First TCP port."),
    robots: int = typer.Option(1, "--robots", min=1, max=64, help="Robots on port, port+1..."),
    pty: bool = typer.Option(False, "--pty", help="Serve on a pseudo-terminal instead of TCP."),
    map_file: Path | None = typer.Option(  # noqa: UP007
        None, "--map", exists=True, dir_okay=False, help="Map: JSON or text walls (x1 y1 x2 y2)."
    ),
    sip_ms: float = typer.Option(100.0, "--sip-ms", min=5.0, max=1000.0, help="SIP period, ms."),
    subtype: str = typer.Option("p3dx", "--subtype", help="Reported robot subtype."),
    bind: str = typer.Option("127.0.0.1", "--bind", help="Address to listen on."),
    time_scale: float = typer.Option(
        1.0, "--time-scale", min=0.1, max=100.0, help="Simulated seconds per wall second."
    ),
) -> None:
    """Run simulated Pioneers speaking ARCOS (like MobileSim) until Ctrl-C."""
    from robocli.robots.pioneer import ROBOT_PARAMS
    from robocli.sim.pioneer import PioneerSim, serve_many
    from robocli.sim.world import World

    if subtype not in ROBOT_PARAMS:
        raise typer.BadParameter(f"unknown subtype {subtype!r}; known: {', '.join(ROBOT_PARAMS)}")
    world = World.load(map_file) if map_file else None
    sims: list[PioneerSim] = []
    with sigterm_as_interrupt():
        try:
            sims = serve_many(
                robots, host=bind, port=port, pty=pty,
                subtype=subtype, sip_ms=sip_ms, world=world, time_scale=time_scale,
            )  # fmt: skip
            for i, simulator in enumerate(sims):
                typer.echo(f"robot {i + 1}: {subtype} on {simulator.pty_path or simulator.url}")
            sys.stdout.flush()
            while True:
                time.sleep(3600)
        except KeyboardInterrupt:
            typer.echo("simulator stopped", err=True)
        finally:
            for simulator in sims:
                simulator.close()


# ---------------------------------------------------------------------- rendering


def _short(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, list) and value and isinstance(value[0], tuple):
        return "[" + ",".join(f"{n}:{r}" for n, r in value) + "]"
    if isinstance(value, dict):
        return "{" + ",".join(f"{k}={v}" for k, v in value.items()) + "}"
    return str(value)


def _print_snapshot(snapshot: dict[str, Any]) -> None:
    ident = snapshot["identity"]
    st = snapshot["state"]
    typer.echo(f"{ident['name']} {ident['type']} {ident['subtype']} on {snapshot['url']}")
    typer.echo(
        f"pose      x {st['x']:+.3f} m  y {st['y']:+.3f} m  th {math.degrees(st['th']):+.1f} deg"
    )
    typer.echo(f"velocity  v {st['v']:+.3f} m/s  w {st['w']:+.3f} rad/s")
    typer.echo(
        f"battery   {st['battery']:.1f} V   motors {'on' if st['motors_enabled'] else 'off'}"
    )
    sonar = " ".join("-" if r is None else f"{r:.2f}" for r in st["sonar"])
    typer.echo(f"sonar (m) {sonar}")


def _render(robot: Pioneer) -> RenderableType:
    from rich.table import Table

    st = robot.state
    table = Table(
        title=f"{robot.identity.name} ({robot.params.subtype}) {robot.transport.url}",
        show_header=False,
        expand=False,
    )
    table.add_column(style="bold")
    table.add_column()
    table.add_row("pose", f"x {st.x:+.3f} m   y {st.y:+.3f} m   th {math.degrees(st.th):+.1f} deg")
    table.add_row("velocity", f"v {st.v:+.3f} m/s   w {math.degrees(st.w):+.1f} deg/s")
    table.add_row(
        "battery",
        f"{st.battery:.1f} V"
        + (f"  {st.state_of_charge:.0%}" if st.state_of_charge is not None else ""),
    )
    table.add_row(
        "motors",
        ("[green]enabled[/]" if st.motors_enabled else "[yellow]disabled[/]")
        + ("  [red]E-STOP[/]" if st.estop else ""),
    )
    table.add_row(
        "bumpers",
        f"front {st.bumpers_front:07b}  rear {st.bumpers_rear:07b}"
        + ("  [red]STALL[/]" if st.stalled else ""),
    )
    max_range = robot.params.sonar_max_range
    for i, rng in enumerate(robot.sonar):
        bar = "" if math.isnan(rng) else "█" * int(30 * min(rng, max_range) / max_range)
        table.add_row(f"sonar {i:2d}", f"{'  -  ' if math.isnan(rng) else f'{rng:5.2f}'} m {bar}")
    s = robot.stats
    table.add_row(
        "link", f"{s.sips} SIPs  {s.bad_checksums} bad checksums  {s.dropped_bytes} bytes dropped"
    )
    return table


def _live_view(robot: Pioneer) -> None:
    from rich.live import Live

    with Live(_render(robot), refresh_per_second=10, screen=False) as live:
        while True:
            robot.wait_for_sip()
            live.update(_render(robot))


_ARROWS = {"A": "up", "B": "down", "C": "right", "D": "left"}


@contextlib.contextmanager
def _raw_terminal() -> Iterator[Any]:
    """Put stdin in cbreak mode; yield ``read_key(timeout) -> name | None``."""
    import termios
    import tty

    fd = sys.stdin.fileno()
    saved = termios.tcgetattr(fd)

    def read_key(timeout: float) -> str | None:
        ready, _, _ = select.select([fd], [], [], timeout)
        if not ready:
            return None
        ch = os.read(fd, 1)
        if ch == b"\x1b":
            more, _, _ = select.select([fd], [], [], 0.01)
            if not more:
                return "esc"
            seq = os.read(fd, 2)
            return _ARROWS.get(seq[-1:].decode(errors="replace"), None)
        if ch == b"\x03":
            return "ctrl-c"
        if ch == b" ":
            return "space"
        return ch.decode(errors="replace")

    try:
        tty.setcbreak(fd)
        yield read_key
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)
