"""``robocli record`` and ``robocli info``: thin layers over :mod:`robocli.io.record`.

``record`` connects to every source given (a Pioneer, arms, a hub, a Hokuyo laser; ``sim``
starts an embedded simulator as everywhere else), records them into one MCAP file on one
timeline, and ends on ``--duration``, ``--count``, Ctrl-C, SIGTERM or a lost link, always
closing the file with its summary. It says on stderr what it recorded. Exit codes: 0 for a
duration or count reached, 130 for Ctrl-C/SIGTERM, the link's own code for a lost link (the
file is written all the same), 1 when the file could not be written.
"""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import typer

from robocli.commands import _common as common
from robocli.commands import _options as opt
from robocli.commands._arm import LINK, ArmLink, arm_link
from robocli.commands._live import FoxgloveHostOpt, FoxgloveOpt, live_view
from robocli.views.recording import progress_text, recorded_text

Compression = Literal["zstd", "lz4", "none"]

if TYPE_CHECKING:
    from robocli.io.record import Recorder
    from robocli.io.record.session import RecordingSession

#: The hub's sensors ``--sensors`` names (robocli.io.record.session.HUB_DEFAULTS).
HUB_SENSORS = ("imu", "adc", "laser", "camera", "gps", "battery", "sysinfo", "depth", "stereo")

def _sensors(text: str) -> list[tuple[str, dict[str, Any]]]:
    """``--sensors``, parsed: a usage error when it names no hub sensor or a bad rate."""
    from robocli.errors import InvalidArgument
    from robocli.io.record.session import hub_sensors

    try:
        return hub_sensors(text)
    except InvalidArgument as exc:
        raise typer.BadParameter(str(exc), param_hint="'--sensors'") from None


@arm_link(motion=False)
def record(
    output: Path = opt.output_option(..., "The recording (MCAP).", dir_okay=False,
                                     metavar="FILE.mcap"),  # fmt: skip
    pioneer: list[str] = opt.device_option("--pioneer", "A Pioneer (port, URL or 'sim'); "
                                           "repeatable.", []),  # fmt: skip
    arm: list[str] = opt.device_option("--arm", "An arm controller (HOST, tcp://HOST or 'sim'; its "
                                       "state port: --state-port); repeatable.", []),  # fmt: skip
    hub: str | None = opt.device_option("--hub", "A sensor hub: HOST[:PORT], tcp://HOST:PORT or "
                                        "'sim'."),  # fmt: skip
    sensors: str = typer.Option("imu,adc", "--sensors", metavar="NAME[:HZ],...", help="Hub "
                                f"sensors: {', '.join(HUB_SENSORS)} (rate in Hz after a colon)."),
    poll: int = typer.Option(20, "--poll", min=1, max=1000, help="Hub pulls per second, Hz."),
    duration: float | None = opt.duration_option(min=0.0, max=1e6),
    count: int | None = opt.count_option(help="Stop after N messages recorded.", min=1),
    compression: Compression = typer.Option("zstd", "--compression", help="Chunk compression."),
    laser: str | None = opt.device_option("--laser", "A Hokuyo laser (device, tcp://host:10940 or "
                                          "'sim')."),  # fmt: skip
    create: list[str] = opt.device_option("--create", "An iRobot Create 2 (port, URL or 'sim'); "
                                          "repeatable.", []),  # fmt: skip
    no_laser: bool = opt.flag("--no-laser", "Do not start a Pioneer simulator's own (ARCOS) "
                              "laser."),  # fmt: skip
    overwrite: bool = opt.OverwriteOpt,
    link: ArmLink = LINK,
    foxglove: int | None = FoxgloveOpt,
    foxglove_host: str = FoxgloveHostOpt,
    ros2: bool = opt.flag("--ros2", "Write a ROS 2 bag: standard messages in CDR that ros2 bag "
                          "play reads (see docs/ros2-bags.md)."),  # fmt: skip
) -> None:
    """Record Pioneers, arms (their state port), a hub, a Hokuyo laser and iRobot Creates
    into one MCAP file (Foxglove's schemas, raw frames for dump --file) until --duration,
    --count or Ctrl-C. The file is made once every source is connected; an existing one is refused
    unless --overwrite. To record an arm while uploading to it: upload --record."""
    from robocli.errors import EXIT_INTERRUPTED
    from robocli.io.record import Recorder
    from robocli.io.record.session import RecordingSession
    from robocli.output import check_output

    if not (pioneer or arm or hub or laser or create):
        raise typer.BadParameter("give at least one of --pioneer, --arm, --hub, --laser, "
                                 "--create")  # fmt: skip
    if output.suffix != ".mcap":
        raise typer.BadParameter(f"--output {output}: a recording needs a .mcap name")
    hub_sensors = _sensors(sensors) if hub else []
    check_output(output, overwrite)  # refused now, before anything connects
    interrupted = False
    with common.sigterm_as_interrupt(), contextlib.ExitStack() as stack:
        view = stack.enter_context(live_view(foxglove, foxglove_host))
        rec = Recorder(output, compression=compression, overwrite=overwrite, deferred=True,
                       ros2=ros2)  # fmt: skip
        if view is not None:
            rec.mirror(view)
        run = RecordingSession(rec, stack)
        try:
            try:
                _connect(run, pioneer, arm, hub, hub_sensors, not no_laser, link, laser)
                for port in create:
                    run.add_create(port, link.timeout)
                rec.begin()  # every source connected: now the file is made
                typer.echo(f"recording to {output} (Ctrl-C stops)", err=True)
                run.run(duration, count, poll, progress_line(run) if sys.stderr.isatty() else None)
            except KeyboardInterrupt:
                interrupted = True
            finally:
                with common.shielded():
                    stack.close()  # devices stop first: their stop sequences are recorded
        finally:
            with common.shielded():
                close_recording(rec, time.monotonic() - run.start)
    if interrupted:
        raise typer.Exit(EXIT_INTERRUPTED)


def close_recording(rec: Recorder, seconds: float) -> None:
    """Close the recording and say what its file holds (on stderr; nothing when it was never
    made); a write failure raises."""
    try:
        rec.close()
    finally:
        if rec.begun:
            if sys.stderr.isatty():
                sys.stderr.write("\r\x1b[K")  # the progress line goes
            typer.echo(recorded_text(rec, seconds), err=True)


def progress_line(run: RecordingSession, every: float = 0.5) -> Callable[[], None]:
    """A function that rewrites one status line on stderr (a terminal's): messages, bytes
    written and the message rate, at most every ``every`` seconds."""
    last = [0.0]

    def show() -> None:
        if time.monotonic() - last[0] >= every:
            last[0] = time.monotonic()
            sys.stderr.write(f"\r\x1b[K{progress_text(run.progress())}")
            sys.stderr.flush()

    return show


def _connect(run: RecordingSession, pioneers: list[str], arms: list[str], hub: str | None,
             sensors: list[tuple[str, dict[str, Any]]], sim_laser: bool, link: ArmLink,
             hokuyo: str | None) -> None:  # fmt: skip
    """Connect every source, ``sim`` starting a simulator on ``run``'s stack."""
    from robocli.commands._arm import arm_host
    from robocli.commands._common import explain_refusal
    from robocli.commands.hub import open_hub
    from robocli.commands.laser import laser_url

    stack = run.stack
    for url in pioneers:
        with explain_refusal(url):
            run.add_pioneer(url, link.timeout, sim_laser)
    wire: dict[str, Any] = {"byte_order": link.byte_order, "real_size": link.real_size,
                            "robot": link.robot}  # fmt: skip
    for host in arms:
        address = stack.enter_context(arm_host(host, link.motion_port, link.state_port, **wire))
        run.add_arm(address, timeout=link.timeout, **wire)
    if hokuyo is not None:
        run.add_laser(stack.enter_context(laser_url(hokuyo)), link.timeout)
    if hub is not None:
        at = stack.enter_context(_hub_address(hub))
        run.add_hub(lambda listeners: open_hub(at, timeout=link.timeout, listeners=listeners), at,
                    sensors)  # fmt: skip


@contextlib.contextmanager
def _hub_address(hub: str) -> Iterator[str]:
    """``hub`` itself, or for ``sim`` an embedded simulated hub on an ephemeral port."""
    if hub != common.SIM:
        yield hub
        return
    from robocli.hub_server import HubServer

    server = HubServer("127.0.0.1", 0, sim=True).start()
    try:
        yield f"127.0.0.1:{server.port}"
    finally:
        server.close()


# ---------------------------------------------------------------------- info


def info(
    file: Path = opt.RecordingArg,
    json_out: bool = opt.json_option(),
) -> None:
    """Summarise a recording like ros2 bag info: duration, start and end, each channel
    with its schema, count, mean rate and largest gap (from the summary section; a file
    cut short is scanned)."""
    from robocli.io.record import info as read_info
    from robocli.views.recording import info_lines

    result = read_info(file)
    if json_out:
        common.print_json(result.as_dict())
        return
    sys.stdout.write("".join(line + "\n" for line in info_lines(result)))
    sys.stdout.flush()
