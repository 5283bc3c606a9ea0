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
import math
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import typer

from robocli.commands._arm import LINK, ArmLink, arm_link
from robocli.commands._common import (
    SIM,
    OverwriteOpt,
    print_json,
    shielded,
    sigterm_as_interrupt,
)
from robocli.commands._live import FoxgloveHostOpt, FoxgloveOpt, live_view
from robocli.commands._options import count_option, duration_option, json_option

Compression = Literal["zstd", "lz4", "none"]

if TYPE_CHECKING:
    from robocli.io.record import Recorder, RecordingInfo

#: Sample rates (Hz) and settings a hub sensor is subscribed with unless ``NAME:RATE``.
HUB_DEFAULTS: dict[str, dict[str, Any]] = {
    "imu": {"rate": 200}, "adc": {"rate": 1000}, "laser": {"rate": 40},
    "camera": {"rate": 30, "resolution": "320x240"}, "gps": {"rate": 5},
    "battery": {"rate": 10}, "sysinfo": {"rate": 10},
    "depth": {"rate": 10, "resolution": "320x240"},
    "stereo": {"rate": 15, "resolution": "320x240"},
}  # fmt: skip


def _sensors(text: str) -> list[tuple[str, dict[str, Any]]]:
    """``imu,adc:500`` -> [("imu", {rate 200}), ("adc", {rate 500})]; usage error otherwise."""
    out = []
    for item in (s.strip() for s in text.split(",")):
        if not item:
            continue
        name, _, rate = item.partition(":")
        name = name.lower()
        if name not in HUB_DEFAULTS:
            raise typer.BadParameter(
                f"{name!r} is not a hub sensor; choose from {', '.join(HUB_DEFAULTS)}",
                param_hint="'--sensors'",
            )
        args = dict(HUB_DEFAULTS[name])
        if rate:
            if not rate.isdigit() or not 1 <= int(rate) <= 65535:
                raise typer.BadParameter(f"{item!r}: the rate is 1..65535 Hz",
                                         param_hint="'--sensors'")  # fmt: skip
            args["rate"] = int(rate)
        out.append((name, args))
    if not out:
        raise typer.BadParameter("name at least one sensor", param_hint="'--sensors'")
    return out


@arm_link(motion=False)
def record(
    output: Path = typer.Option(
        ..., "--output", "-o", dir_okay=False, metavar="FILE.mcap", help="The recording (MCAP)."
    ),
    pioneer: list[str] = typer.Option(
        [], "--pioneer", metavar="URL", help="A Pioneer (port, URL or 'sim'); repeatable."
    ),
    arm: list[str] = typer.Option(
        [],
        "--arm",
        metavar="URL",
        help="An arm controller (HOST, tcp://HOST or 'sim'; its state "
        "port: --state-port); repeatable.",
    ),
    hub: str | None = typer.Option(
        None, "--hub", metavar="URL", help="A sensor hub: HOST[:PORT], tcp://HOST:PORT or 'sim'."
    ),
    sensors: str = typer.Option(
        "imu,adc",
        "--sensors",
        metavar="NAME[:HZ],...",
        help="Hub sensors: " + ", ".join(HUB_DEFAULTS) + " (rate in Hz after a colon).",
    ),
    poll: int = typer.Option(20, "--poll", min=1, max=1000, help="Hub pulls per second, Hz."),
    duration: float | None = duration_option(min=0.0, max=1e6),
    count: int | None = count_option(help="Stop after N messages recorded.", min=1),
    compression: Compression = typer.Option("zstd", "--compression", help="Chunk compression."),
    laser: str | None = typer.Option(
        None, "--laser", metavar="URL", help="A Hokuyo laser (device, tcp://host:10940 or 'sim')."
    ),
    create: list[str] = typer.Option(
        [], "--create", metavar="URL", help="An iRobot Create 2 (port, URL or 'sim'); repeatable."
    ),
    no_laser: bool = typer.Option(
        False, "--no-laser", help="Do not start a Pioneer simulator's own (ARCOS) laser."
    ),
    overwrite: bool = OverwriteOpt,
    link: ArmLink = LINK,
    foxglove: int | None = FoxgloveOpt,
    foxglove_host: str = FoxgloveHostOpt,
    ros2: bool = typer.Option(
        False,
        "--ros2",
        help="Write a ROS 2 bag: standard messages "
        "in CDR that ros2 bag play reads (see docs/ros2-bags.md).",
    ),
) -> None:
    """Record Pioneers, arms (their state port), a hub, a Hokuyo laser and iRobot Creates
    into one MCAP file (Foxglove's schemas, raw frames for dump --file) until --duration,
    --count or Ctrl-C. The file is made once every source is connected; an existing one is refused
    unless --overwrite. To record an arm while uploading to it: upload --record."""
    from robocli.errors import EXIT_INTERRUPTED
    from robocli.io.record import COMPRESSIONS, Recorder
    from robocli.output import check_output

    if not (pioneer or arm or hub or laser or create):
        raise typer.BadParameter("give at least one of --pioneer, --arm, --hub, --laser, "
                                 "--create")  # fmt: skip
    if output.suffix != ".mcap":
        raise typer.BadParameter(f"--output {output}: a recording needs a .mcap name")
    if compression not in COMPRESSIONS:
        raise typer.BadParameter(f"--compression is one of {', '.join(COMPRESSIONS)}, "
                                 f"not {compression!r}")  # fmt: skip
    hub_sensors = _sensors(sensors) if hub else []
    check_output(output, overwrite)  # refused now, before anything connects
    start = time.monotonic()
    interrupted = False
    with sigterm_as_interrupt(), contextlib.ExitStack() as stack:
        view = stack.enter_context(live_view(foxglove, foxglove_host))
        rec = Recorder(output, compression=compression, overwrite=overwrite, deferred=True,
                       ros2=ros2)  # fmt: skip
        if view is not None:
            rec.mirror(view)
        try:
            try:
                devices = _connect(stack, rec, pioneer, arm, hub, hub_sensors, not no_laser,
                                   link, laser)  # fmt: skip
                devices.update(_connect_creates(stack, rec, create, link.timeout))
                rec.begin()  # every source connected: now the file is made
                typer.echo(f"recording to {output} (Ctrl-C stops)", err=True)
                start = time.monotonic()  # --duration counts from here, not from connecting
                done = _until(rec, start, duration, count, devices)
                if hub is not None:
                    from robocli.io.record import pull_hub

                    pull_hub(devices["hub"], [n for n, _ in hub_sensors], poll, done)
                else:
                    while not done():
                        time.sleep(0.05)
            except KeyboardInterrupt:
                interrupted = True
            finally:
                with shielded():
                    stack.close()  # devices stop first: their stop sequences are recorded
        finally:
            with shielded():
                close_recording(rec, time.monotonic() - start)
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
            st = rec.stats
            lost = f", {st.lost} not written (writing failed)" if st.lost else ""
            why = "not written" if rec.error is not None else "the disk was too slow"
            dropped = f", {st.dropped} dropped ({why})" if st.dropped else ""
            typer.echo(f"recorded {st.messages} messages in {seconds:.1f} s to "
                       f"{rec.path}{lost}{dropped}", err=True)  # fmt: skip


def progress_line(rec: Recorder, start: float, every: float = 0.5) -> Callable[[], None]:
    """A function that rewrites one status line on stderr (a terminal's): messages, bytes
    written and the message rate, at most every ``every`` seconds."""
    import os

    last = [0.0]

    def show() -> None:
        now = time.monotonic()
        if now - last[0] < every:
            return
        last[0] = now
        try:
            size = os.stat(rec.path).st_size
        except OSError:
            size = 0
        n, seconds = rec.stats.added, max(now - start, 1e-9)
        sys.stderr.write(f"\r\x1b[K{n} messages, {_size(size)}, {n / seconds:.0f} msg/s, "
                         f"{seconds:.0f} s")  # fmt: skip
        sys.stderr.flush()

    return show


def _until(rec: Recorder, start: float, duration: float | None, count: int | None,
           devices: dict[str, Any]) -> Callable[[], bool]:  # fmt: skip
    """A ``done()`` for the recording loop: True once the duration or count is reached;
    raises the error of a device whose link was lost."""
    end = start + duration if duration is not None else math.inf
    show = progress_line(rec, start) if sys.stderr.isatty() else None  # quiet in a pipe

    def done() -> bool:
        rec.check()  # the disk is full: stop now, what was written stays readable
        if show is not None:
            show()
        for name, device in devices.items():
            if name.startswith("pioneer") and not device.alive:
                device.wait_for_sip(0)  # raises why the session ended
            elif name.startswith("arm"):
                device.check()
            elif name.startswith(("laser", "create")):
                device.session.check()
        return time.monotonic() >= end or (count is not None and rec.stats.added >= count)

    return done


def _connect(stack: contextlib.ExitStack, rec: Recorder, pioneers: list[str], arms: list[str],
             hub: str | None, sensors: list[tuple[str, dict[str, Any]]], laser: bool,
             link: ArmLink, hokuyo: str | None = None) -> dict[str, Any]:  # fmt: skip
    """Connect every source (simulators started on ``stack``) and add it to ``rec``, each
    recorded from its first byte; ``hokuyo``: a Hokuyo laser's URL (streamed with MD)."""
    from robocli.commands._arm import arm_host, connect_at
    from robocli.commands._common import explain_refusal
    from robocli.devices.pioneer import Pioneer
    from robocli.io.record.arm import arm_links

    devices: dict[str, Any] = {}
    for port in pioneers:
        url = port
        listener = rec.listener("pioneer", "arcos", url=url)
        with explain_refusal(url):
            robot = stack.enter_context(
                Pioneer.connect(url, listeners=[listener], timeout=link.timeout)
            )
        name = rec.add(robot, listener.name)
        devices[name] = robot
        if laser and robot.sim is not None:
            robot.sim.start_laser()
    for host in arms:
        address = stack.enter_context(arm_host(host, link.motion_port, link.state_port,
                                               link.byte_order, link.real_size,
                                               link.robot))  # fmt: skip
        name, links = arm_links(rec, "arm", byte_order=link.byte_order,
                                real_size=link.real_size, ports="state")  # fmt: skip
        device = stack.enter_context(connect_at(address, link, stop_on_failure=False,
                                                listeners={"state": [links["state"]]}))  # fmt: skip
        devices[rec.add(device, name)] = device
    if hokuyo is not None:  # on the first Pioneer, as its robot model says
        first = next((n for n in devices if n.startswith("pioneer")), None)
        on = {} if first is None else {"parent": f"{first}/base_link",
                                       "mount": devices[first].params.laser_mount}  # fmt: skip
        devices.update(_connect_laser(stack, rec, hokuyo, link.timeout, on))
    if hub is not None:
        hub_at = stack.enter_context(_hub_address(hub))
        from robocli.commands.hub import open_hub

        names = [n for n, _ in sensors]
        listener = rec.listener("hub", "ros4mat", url=hub_at, sensors=",".join(names))
        client = stack.enter_context(open_hub(hub_at, timeout=link.timeout,
                                              listeners=[listener]))  # fmt: skip
        rec.add(client, listener.name, sensors=names)
        for name, args in sensors:
            client.subscribe(name, **args)
        devices["hub"] = client
    return devices


def _connect_creates(stack: contextlib.ExitStack, rec: Recorder, ports: list[str],
                     timeout: float) -> dict[str, Any]:  # fmt: skip
    """Each Create of ``--create``, recorded from its first byte (closing pauses its stream)."""
    from robocli.commands.create import connect_create

    return {f"create{i or ''}": connect_create(stack, rec, p, timeout) for i, p in enumerate(ports)}


def _connect_laser(stack: contextlib.ExitStack, rec: Recorder, port: str, timeout: float,
                   on: dict[str, Any]) -> dict[str, Any]:  # fmt: skip
    """A Hokuyo recorded from its handshake on, streaming (closing sends QT, recorded);
    ``on``: the frame it is mounted on and where (see :func:`attach_laser`)."""
    from robocli.commands.laser import laser_url
    from robocli.devices.laser import Laser

    url = stack.enter_context(laser_url(port))
    listener = rec.listener("laser", "scip2", url=url)
    laser = stack.enter_context(Laser.connect(url, timeout=max(timeout, 2.0), listeners=[listener]))
    name = rec.add(laser, listener.name, **on)
    laser.start()
    return {name: laser}


@contextlib.contextmanager
def _hub_address(hub: str) -> Iterator[str]:
    """``hub`` itself, or for ``sim`` an embedded simulated hub on an ephemeral port."""
    if hub != SIM:
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
    file: Path = typer.Argument(
        ..., exists=True, dir_okay=False, metavar="FILE", help="A recording (.mcap)."
    ),
    json_out: bool = json_option(),
) -> None:
    """Summarise a recording like ros2 bag info: duration, start and end, each channel
    with its schema, count, mean rate and largest gap (from the summary section; a file
    cut short is scanned)."""
    from robocli.io.record import info as read_info

    result = read_info(file)
    if json_out:
        print_json(result.as_dict())
        return
    _print_info(result)


def _when(ns: int) -> str:
    try:  # a file's times may be anything: a year past 9999 is shown as its number
        stamp = time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(ns // 1_000_000_000))
    except (OverflowError, OSError, ValueError):
        return f"{ns / 1e9:.6f}"
    return f"{stamp}.{ns % 1_000_000_000 // 1000:06d} ({ns / 1e9:.6f})"


def _size(n: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB"):
        if n < 1024 or unit == "GiB":
            return f"{n:.1f} {unit}" if unit != "B" else f"{int(n)} B"
        n /= 1024
    return f"{n:.1f} GiB"  # pragma: no cover


def _print_info(r: RecordingInfo) -> None:
    out = sys.stdout.write
    out(f"File:        {r.path}\n")
    out(f"Size:        {_size(r.size)}\n")
    if r.library:
        out(f"Written by:  {r.library}\n")
    if not r.summary:
        cut = " (cut short: everything up to the last complete record was read)" \
            if r.truncated else ""  # fmt: skip
        out(f"Summary:     none, the file was scanned{cut}\n")
        if r.truncated and r.readable_bytes > 8:  # its header at least is whole
            out(f"Recover:     robocli recover {r.path}\n")
    out(f"Duration:    {r.duration_s:.3f} s\n")
    if r.messages:
        out(f"Start:       {_when(r.start_ns)}\n")
        out(f"End:         {_when(r.end_ns)}\n")
    out(f"Messages:    {r.messages}\n")
    out(f"Chunks:      {r.chunks}" + (f" ({', '.join(r.compression)})" if r.compression else "")
        + "\n")  # fmt: skip
    out(f"Channels:    {len(r.channels)}\n")
    width = max((len(c.topic) for c in r.channels), default=5)
    swidth = max((len(c.schema or c.encoding) for c in r.channels), default=6)
    out(f"  {'topic':<{width}}  {'schema':<{swidth}}  {'count':>8}  {'rate Hz':>9}  "
        f"{'largest gap s':>13}\n")  # fmt: skip
    for c in r.channels:
        rate = f"{c.rate_hz:9.2f}" if c.rate_hz is not None else f"{'-':>9}"
        out(f"  {c.topic:<{width}}  {c.schema or c.encoding:<{swidth}}  {c.count:>8}  {rate}  "
            f"{c.largest_gap_s:13.3f}\n")  # fmt: skip
    sys.stdout.flush()
