"""``robocli connect|sim|dump laser``: Hokuyo scanners over SCIP 2.0, thin layers over
:class:`robocli.devices.laser.Laser` and :class:`robocli.sim.hokuyo.HokuyoSim`.

JSON output is SI: ranges in metres (None where the sensor sent an error code, the code in
``codes``), angles in radians (counter-clockwise, 0 ahead), ``t`` in Unix epoch seconds
(the sensor's stamp on the host clock).
"""

from __future__ import annotations

import contextlib
import math
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import typer

from robocli.commands import _common as common
from robocli.commands import _options as opt
from robocli.views.laser import identity_lines, scan_json, scan_line

if TYPE_CHECKING:
    from robocli.devices.laser import Laser

MODELS = ("urg-04lx", "utm-30lx", "ust-10lx")
Model = Literal["urg-04lx", "utm-30lx", "ust-10lx"]


ModelOpt = typer.Option("utm-30lx", "--model", help="The simulated model.")
LaserArg = opt.device_argument("laser")
TimeoutOpt = opt.timeout_option(2.0, "Seconds to wait for each reply (scans: at least 16 scan "
                                "periods).", 0.1, 3600.0, metavar="SECONDS")  # fmt: skip
BaudOpt = opt.baud_option(115200)


@contextlib.contextmanager
def laser_url(port: str, model: str = "utm-30lx") -> Iterator[str]:
    """Yield a URL for ``port``; for ``sim`` an in-process simulator of ``model`` on an
    ephemeral loopback port, stopped afterwards."""
    if port != common.SIM:
        yield port
        return
    from robocli.sim.hokuyo import HokuyoSim

    with HokuyoSim(model) as sim:
        yield sim.serve_tcp("127.0.0.1", 0)


@contextlib.contextmanager
def connected(port: str, model: str, **options: Any) -> Iterator[Laser]:
    """A connected laser on ``port`` (``sim``: an embedded simulator); Ctrl-C and SIGTERM
    close it (QT sent)."""
    from robocli.devices.laser import Laser

    with common.reader_may_leave(), common.sigterm_as_interrupt(), laser_url(port, model) as url:
        with Laser.connect(url, **options) as laser:
            yield laser


def connect(
    port: str = LaserArg,
    once: bool = opt.flag("--once", "Print the identity and one scan, exit."),
    json_out: bool = opt.json_option(),
    start: int | None = typer.Option(None, "--start", min=0, max=9999, help="First step."),
    end: int | None = typer.Option(None, "--end", min=0, max=9999, help="Last step."),
    cluster: int = typer.Option(1, "--cluster", min=1, max=99, help="Steps per value."),
    intensity: bool = opt.flag("--intensity", "Ranges and intensities (ME)."),
    count: int = opt.count_option(0, "Stop after N scans (0: none).", min=0),
    model: Model = ModelOpt,
    baud: int = BaudOpt,
    timeout: float = TimeoutOpt,
) -> None:
    """Connect to a Hokuyo laser: its identity, then its scans live until Ctrl-C
    (--once: one scan; --json: JSON Lines, SI units)."""
    if start is not None and end is not None and end < start:
        raise typer.BadParameter(f"--end {end} is before --start {start}")
    area: dict[str, Any] = {"start": start, "end": end, "cluster": cluster}
    with connected(port, model, baudrate=baud, timeout=timeout) as laser:
        info = laser.info
        assert info is not None
        if once:
            scan = laser.scan(intensity=intensity, **area)
            if json_out:
                identity = {"identity": common.rounded(info.as_dict())}
                common.print_json({**identity, **scan_json(laser, scan)})
            else:
                _print_identity(laser)
                typer.echo(scan_line(scan))
            return
        if not json_out:
            _print_identity(laser)
        n = 0
        # closed here, not when the generator is collected: its QT (and the error of a
        # sensor that does not answer it) belongs to this command, not to the garbage collector
        with contextlib.closing(laser.scans(None, intensity=intensity, **area)) as scans:
            for scan in scans:
                if json_out:
                    common.print_json(scan_json(laser, scan))
                else:
                    typer.echo(scan_line(scan))
                    sys.stdout.flush()
                n += 1
                if count and n >= count:
                    break


def _print_identity(laser: Laser) -> None:
    for line in identity_lines(laser):
        typer.echo(line)


def simulate(
    model: Model = ModelOpt,
    port: int | None = opt.port_option(None, "TCP port (default 10940)."),
    pty: bool = opt.flag("--pty", "Serve on a pseudo-terminal (USB) instead."),
    map_file: Path | None = opt.MapOpt,
    pose: str | None = opt.pose_option("Scanner pose in the map: m, m, rad."),
    bind: str = opt.BindOpt,
    time_scale: float = opt.TimeScaleOpt,
) -> None:
    """Run a simulated Hokuyo laser speaking SCIP 2.0 until Ctrl-C."""
    from robocli.commands.pioneer import _load_map
    from robocli.sim.hokuyo import MODELS as SIM_MODELS
    from robocli.sim.hokuyo import HokuyoSim
    from robocli.sim.world import World

    world = _load_map(World, map_file) if map_file else None
    where = _pose(pose) if pose else None
    with common.sigterm_as_interrupt(), HokuyoSim(model, world=world, pose=where,
                                                  time_scale=time_scale) as sim:  # fmt: skip
        if pty:
            url = sim.serve_pty()
        else:
            with common.listening(bind):
                tcp_port = SIM_MODELS[model].tcp_port if port is None else port
                url = sim.serve_tcp(common.bind_address(bind), tcp_port)
        typer.echo(f"laser: {model} on {url}")
        common.wait_forever()


def _pose(text: str) -> tuple[float, float, float]:
    try:
        x, y, th = (float(v) for v in text.split(","))
    except ValueError:
        raise typer.BadParameter(
            f"{text!r} is not X,Y,TH (m, m, rad)", param_hint="'--pose'"
        ) from None
    if not all(math.isfinite(v) for v in (x, y, th)):
        raise typer.BadParameter(f"{text!r}: finite numbers only", param_hint="'--pose'")
    return x, y, th
