"""``robocli dump pioneer|arm|hub|laser``: every packet of a session, named and decoded, like
a protocol analyser; thin layers over :mod:`robocli.analysis` (which names, decodes and
orders the packets) that render them as text lines or JSON Lines.

Live, ``dump`` is a client of the device (``dump arm`` opens both ports; with ``--listen``
it relays other programs' sessions as a recording proxy, as ``dump hub`` always does);
``--file`` decodes a capture instead, and ``--output`` records one.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import typer

from robocli.analysis import text
from robocli.commands import _common as common
from robocli.commands import _options as opt
from robocli.commands._arm import LINK, ArmLink, arm_host, arm_link
from robocli.commands.laser import BaudOpt as LaserBaudOpt
from robocli.commands.laser import Model, ModelOpt, laser_url
from robocli.commands.laser import TimeoutOpt as LaserTimeoutOpt
from robocli.commands.pioneer import BaudOpt, SubtypeOpt, TimeoutOpt, connected, start_laser
from robocli.defaults import ARM_ENV, HUB_ENV, PIONEER_ENV
from robocli.output import same_file

if TYPE_CHECKING:
    from robocli.analysis.packets import Packet, PacketLog

#: Messages dump arm queues for the output at most (bounded memory when stdout stalls).
MAX_QUEUED = 20_000
_HexOpt = opt.flag("--hex", "Also print the raw frame bytes.")
_MessagesOpt = typer.Option(0, "--count", "-n", min=0, help="Stop after N messages (0: none).")


def _device(kind: str, envvar: str) -> Any:
    return typer.Argument(None, help=f"The {kind}: {opt.DEVICE_FORMS[kind]}; omit with --file.",
                          show_default=False, metavar="URL", envvar=envvar, show_envvar=True)


def _capture(help: str, metavar: str | None = "CAPTURE") -> Any:
    return typer.Option(None, "--file", "-f", metavar=metavar, exists=True, dir_okay=False,
                        help=help)  # fmt: skip


def pioneer(
    ctx: typer.Context,
    port: str | None = _device("pioneer", PIONEER_ENV),
    count: int = opt.count_option(0, "Stop after N packets (0: none).", min=0),
    hex_out: bool = _HexOpt,
    json_out: bool = opt.json_option(),
    output: Path | None = opt.output_option(None, "Also record the packets to a .jsonl capture "
                                            "(what --file reads).", metavar="FILE.jsonl",
                                            dir_okay=False),  # fmt: skip
    overwrite: bool = opt.OverwriteOpt,
    laser: bool = opt.flag("--laser", "Start a simulator's laser, to see its packets (0x60/0x61)."),
    file: Path | None = _capture("Decode a capture (.jsonl trace or raw bytes) instead of a "
                                 "robot."),  # fmt: skip
    subtype: str | None = SubtypeOpt,
    baud: int = BaudOpt,
    timeout: float = TimeoutOpt,
) -> None:
    """Print every packet in both directions, in time order, with its name and decoded
    fields (raw units; lines cut at 160 characters unless -v)."""
    full = bool(ctx.find_root().params.get("verbose"))
    port = _one(ctx, "port", port, file, output)
    log = _log("arcos", partial(_pioneer_line, json_out=json_out, hex_out=hex_out, full=full),
               count, output, overwrite)  # fmt: skip
    if port is None:
        _replay(log, file, "arcos")
        return
    log.start_now()  # t 0, for JSON and a capture being written
    try:
        with connected(port, listeners=[log.listener()], subtype=subtype, baudrate=baud,
                       timeout=timeout) as robot:  # fmt: skip
            log.open()  # connected: now the capture is made
            if laser:
                start_laser(robot, wait=False)
            from robocli.analysis.sessions import pioneer_check

            log.follow(pioneer_check(robot))
    finally:
        with common.reader_may_leave():
            log.drain()  # what was still queued, and the close sequence
        log.close()


@arm_link()
def arm(
    ctx: typer.Context,
    host: str | None = _device("arm", ARM_ENV),
    count: int = _MessagesOpt,
    hex_out: bool = _HexOpt,
    json_out: bool = opt.json_option(),
    output: Path | None = opt.output_option(None, "Also record to a .jsonl capture.",
                                            dir_okay=False),  # fmt: skip
    overwrite: bool = opt.OverwriteOpt,
    file: Path | None = _capture("Decode a capture instead.", None),
    ports: Literal["both", "motion", "state"] = typer.Option("both", "--ports", help="both (two "
                                                             "clients), motion or state."),
    listen: str | None = typer.Option(None, "--listen", metavar="[ADDR:]PORT", help="Be a "
                                      "recording proxy: other programs connect to the motion "
                                      "port PORT and the state port PORT+2 (0: ephemeral) "
                                      "instead of the controller."),  # fmt: skip
    link: ArmLink = LINK,
) -> None:
    """Print every Simple Message on the motion and state ports, in time order, named and
    decoded (joints in rad)."""
    from robocli.analysis import sessions
    from robocli.kinematics import load_model

    host = _one(ctx, "host", host, file, None)
    if listen is not None and host is None:
        raise typer.BadParameter("--listen relays to a HOST; not with --file")
    bind_to = _listen_address(listen) if listen is not None else None
    protocol = f"sm-{link.byte_order[0]}e"
    log = _log(protocol, partial(_arm_line, json_out=json_out, hex_out=hex_out), count, output,
               overwrite, n_joints=load_model(link.robot).n_joints, real=link.real_size,
               bound=MAX_QUEUED)  # fmt: skip
    with common.reader_may_leave(), common.sigterm_as_interrupt():
        if host is None:
            _replay(log, file, protocol)
            return
        log.start_now()
        wire: dict[str, Any] = {"byte_order": link.byte_order, "real_size": link.real_size,
                                "robot": link.robot}  # fmt: skip
        with arm_host(host, link.motion_port, link.state_port, **wire) as address:
            try:
                sessions.arm_session(log, address, ports, listen=bind_to, timeout=link.timeout,
                                     on_relays=lambda text: typer.echo(f"dump: {text}", err=True),
                                     **wire)  # fmt: skip
            finally:
                if log.dropped:
                    typer.echo(f"robocli: {log.dropped} messages not shown: the output was too "
                               "slow", err=True)  # fmt: skip


def hub(
    ctx: typer.Context,
    host: str | None = _device("hub", HUB_ENV),
    listen: str = typer.Option("127.0.0.1:1501", "--listen",
                               help="Where clients connect instead of the hub."),
    count: int = _MessagesOpt,
    hex_out: bool = opt.flag("--hex", "Also print the raw bytes."),
    json_out: bool = opt.json_option(),
    output: Path | None = opt.output_option(None, "Also record the session (.jsonl capture)."),
    overwrite: bool = opt.OverwriteOpt,
    file: Path | None = _capture("Decode a capture (dump hub -o, or a record .mcap) instead."),
) -> None:
    """A recording proxy: point ros4mat clients at --listen; every message both ways is
    printed, named and decoded, and passed on unchanged. --file decodes a capture."""
    from robocli.analysis.ros4mat import check_upstream
    from robocli.analysis.sessions import hub_session
    from robocli.devices.hub.client import parse_hub
    from robocli.errors import EXIT_INTERRUPTED
    from robocli.transports import parse_address

    host = _one(ctx, "host", host, file, output)
    log = _log("ros4mat", partial(_hub_line, json_out=json_out, hex_out=hex_out), count, output,
               overwrite)  # fmt: skip
    if host is None:
        _replay(log, file, "ros4mat")
        return
    upstream = parse_hub(host)
    bind, port = parse_address(listen, 1501, default_host="127.0.0.1", what="--listen",
                               port_range=(0, 65535))  # fmt: skip
    check_upstream(*upstream)
    with common.sigterm_as_interrupt(), common.reader_may_leave():
        try:
            hub_session(log, upstream, bind, port, lambda at: typer.echo(
                f"dump: clients connect to {bind}:{at}, relayed to {upstream[0]}:{upstream[1]}",
                err=True))  # fmt: skip
        except KeyboardInterrupt:
            raise typer.Exit(EXIT_INTERRUPTED) from None
        finally:
            log.close()


def laser(
    port: str | None = opt.device_argument("laser", default=None),
    count: int = opt.count_option(3, "Scans to stream live (0: until Ctrl-C).", min=0),
    json_out: bool = opt.json_option(),
    file: Path | None = _capture("Decode a capture (.jsonl chunks, a .mcap recording or raw "
                                 "sensor bytes)."),  # fmt: skip
    model: Model = ModelOpt,
    baud: int = LaserBaudOpt,
    timeout: float = LaserTimeoutOpt,
) -> None:
    """Show every SCIP line of a laser session both ways, named and decoded."""
    from robocli.analysis.sessions import laser_check

    if (port is None) == (file is None):
        raise typer.BadParameter("give a URL or --file CAPTURE (one of them)")
    log = _log("scip2", partial(_laser_lines, t0=[], json_out=json_out), 0, None, False)
    with common.reader_may_leave(), common.sigterm_as_interrupt():
        if file is not None:
            _replay(log, file, "scip2")
            return
        from robocli.devices.laser import Laser

        assert port is not None
        log.start(time.time() - time.monotonic())  # the link stamps on time.monotonic()
        with laser_url(port, model) as url:
            with Laser.connect(url, baudrate=baud, timeout=timeout, listeners=[log.direct]) as dev:
                laser_check(log, dev, count)


# ---------------------------------------------------------------------- the steps


def _one(ctx: typer.Context, name: str, device: str | None, file: Path | None,
         output: Path | None) -> str | None:  # fmt: skip
    """The device, or None for ``--file`` (whose choice overrides the device's environment
    variable); a usage error unless exactly one is given, or for ``--output`` on the file."""
    if file is not None and common.from_env(ctx, name):
        device = None
    if name == "port" and (device is None) == (file is None):  # dump pioneer's own words
        raise typer.BadParameter("give PORT or --file" + (", not both" if file else ""))
    if (device is None) == (file is None):
        raise typer.BadParameter("give HOST or --file (one of them)")
    if output is not None and file is not None and same_file(output, file):
        raise typer.BadParameter(f"--output {output} is the --file being read: it would be emptied")
    return device


def _log(protocol: str, render: Callable[[PacketLog, Packet], None], count: int,
         output: Path | None, overwrite: bool, bound: int = 0,
         **options: Any) -> PacketLog:  # fmt: skip
    """A packet log of ``protocol`` handing each packet to ``render``, with a capture
    writer on ``output`` checked now (a .jsonl name, no existing file without --overwrite: exit 2
    before anything connects) and made by ``log.open()`` once the session is connected."""
    from robocli.analysis.packets import PacketLog
    from robocli.analysis.sessions import decoder

    writer = None
    if output is not None:
        from robocli.io.capture import CaptureWriter

        if output.suffix != ".jsonl":
            raise typer.BadParameter(f"{output}: the capture format needs a .jsonl name",
                                     param_hint="'--output'")  # fmt: skip
        writer = CaptureWriter(output, overwrite, deferred=True)
    log: PacketLog = PacketLog(decoder(protocol, **options), lambda p: render(log, p),
                               count=count, writer=writer, bound=bound)  # fmt: skip
    return log


def _replay(log: PacketLog, file: Path | None, protocol: str) -> None:
    """Show a capture's packets (exit 1 when it holds none); a note of dropped bytes (of a
    Pioneer's or a laser's capture)."""
    from robocli.analysis.sessions import NOUNS, replay_capture

    assert file is not None
    log.open()
    try:
        with common.reader_may_leave(), common.sigterm_as_interrupt():
            stats = replay_capture(log, file, protocol)
    finally:
        log.close()
    if stats is not None and stats.dropped_bytes and protocol in NOUNS:
        typer.echo(f"robocli: {file}: {stats.frames} {NOUNS[protocol]} decoded, "
                   f"{stats.dropped_bytes} bytes dropped", err=True)  # fmt: skip


def _listen_address(text: str) -> tuple[str, int]:
    """``--listen [ADDR:]PORT`` -> (address, motion port); the state port is 2 above."""
    from robocli.transports import InvalidURL, parse_address

    try:
        return parse_address(text, None, default_host="127.0.0.1", port_range=(0, 65533))
    except InvalidURL as exc:
        raise typer.BadParameter(
            f"--listen is [ADDR:]PORT with PORT 0 or 1..65533, not {text!r} ({exc.reason})"
        ) from None


# ---------------------------------------------------------------------- rendering


def _out(line: str, payload: bytes | None = None, indent: int = 13) -> None:
    sys.stdout.write(line + "\n")
    if payload is not None:
        sys.stdout.write(f"{'':{indent}}{payload.hex(' ')}\n")
    sys.stdout.flush()


def _mark() -> str:
    return text.ellipsis(getattr(sys.stdout, "encoding", None))


def _pioneer_line(log: PacketLog, p: Packet, json_out: bool, hex_out: bool, full: bool) -> None:
    if json_out:
        return common.print_json(text.pioneer_record(log, p))
    _out(text.pioneer_line(p, full, _mark()), p.frame if hex_out else None)


def _arm_line(log: PacketLog, p: Packet, json_out: bool, hex_out: bool) -> None:
    if json_out:
        return common.print_json(text.arm_record(log, p, hex_out))
    _out(text.arm_line(p, _mark()), p.frame if hex_out else None)


def _hub_line(log: PacketLog, p: Packet, json_out: bool, hex_out: bool) -> None:
    if json_out:
        return _out(text.hub_record(log, p, hex_out))
    _out(text.hub_line(p), p.frame[:256] if hex_out else None, 14)


def _laser_lines(log: PacketLog, p: Packet, t0: list[float], json_out: bool) -> None:
    for line in text.laser_lines(log, p, t0, json_out):
        common.print_json(line) if json_out else typer.echo(line)
