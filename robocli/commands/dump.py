"""``robocli dump pioneer|arm|hub``: every packet of a session, named and decoded, like a
protocol analyser; thin layers over the devices' links, :mod:`robocli.analysis.proxy` and
:mod:`robocli.io.capture`.

``dump pioneer`` and ``dump arm`` open the robot's link(s) as a client and show both
directions in time order (sent and received packets come from different threads, so each
waits :data:`REORDER` s for older ones); ``--file`` decodes a capture instead, ``--output``
records one. ``dump arm`` opens the motion and the state port as two clients (``--ports``
picks one; an ABB takes one client per port, so a dump holding the motion port keeps others
from uploading), or with ``--listen`` relays other programs' sessions as a recording proxy;
``dump hub`` is always such a proxy, between ros4mat clients and the hub.
The views that name and render the packets are in :mod:`robocli.commands._packets`.
"""

from __future__ import annotations

import contextlib
import os
import queue
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import typer

from robocli.commands._arm import LINK, ArmLink, arm_host, arm_link
from robocli.commands._common import (
    OverwriteOpt,
    from_env,
    listening,
    reader_may_leave,
    sigterm_as_interrupt,
)
from robocli.commands._options import DEVICE_FORMS, json_option
from robocli.commands.pioneer import BaudOpt, SubtypeOpt, TimeoutOpt, connected, start_laser
from robocli.defaults import ARM_ENV, HUB_ENV, PIONEER_ENV

if TYPE_CHECKING:
    from robocli.io.capture import CaptureStats

#: Messages dump arm queues for the output at most (bounded memory when stdout stalls).
MAX_QUEUED = 20_000
#: How long a packet waits for older ones from another thread before it is printed (s).
REORDER = 0.05


def pioneer(
    ctx: typer.Context,
    port: str | None = typer.Argument(
        None,
        help=f"The pioneer: {DEVICE_FORMS['pioneer']}; omit with --file.",
        show_default=False,
        metavar="URL",
        envvar=PIONEER_ENV,
        show_envvar=True,
    ),
    count: int = typer.Option(
        0, "--count", "-n", min=0, metavar="N", help="Stop after N packets (0: none)."
    ),
    hex_out: bool = typer.Option(False, "--hex", help="Also print the raw frame bytes."),
    json_out: bool = json_option(),
    output: Path | None = typer.Option(
        None,
        "--output",
        "-o",
        metavar="FILE.jsonl",
        dir_okay=False,
        help="Also record the packets to a .jsonl capture (what --file reads).",
    ),
    overwrite: bool = OverwriteOpt,
    laser: bool = typer.Option(
        False, "--laser", help="Start a simulator's laser, to see its packets (0x60/0x61)."
    ),
    file: Path | None = typer.Option(
        None,
        "--file",
        "-f",
        metavar="CAPTURE",
        exists=True,
        dir_okay=False,
        help="Decode a capture (.jsonl trace or raw bytes) instead of a robot.",
    ),
    subtype: str | None = SubtypeOpt,
    baud: int = BaudOpt,
    timeout: float = TimeoutOpt,
) -> None:
    """Print every packet in both directions, in time order, with its name and decoded
    fields (raw units; lines cut at 160 characters unless -v)."""
    from robocli.commands._packets import PacketView

    if file is not None and from_env(ctx, "port"):
        port = None  # $ROBOCLI_PIONEER names a robot; --file reads a capture instead
    if port is None and file is None:
        raise typer.BadParameter("give PORT or --file")
    if port is not None and file is not None:
        raise typer.BadParameter("give PORT or --file, not both")
    if output is not None and file is not None and _same_file(output, file):
        raise typer.BadParameter(f"--output {output} is the --file being read: it would be emptied")
    full = bool(ctx.find_root().params.get("verbose"))
    writer = _capture(output, overwrite)
    try:
        view = PacketView(json_out=json_out, hex_out=hex_out, full=full, count=count, writer=writer)
        if file is not None:
            _begin(view)
            _pioneer_file(view, file)
        else:
            assert port is not None
            _pioneer_live(view, port, laser, subtype=subtype, baudrate=baud, timeout=timeout)
    finally:
        if writer is not None:
            writer.close()


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist (yet)
        return False


def _pioneer_file(view: Any, file: Path) -> None:
    """Show the packets of a capture, streamed; exit 1 when it holds none, or when
    :data:`~robocli.io.capture.MAX_GAP` bytes come without one (``/dev/zero``). Bytes that
    formed no packet are said on stderr."""
    from robocli.errors import RobocliError

    with reader_may_leave(), sigterm_as_interrupt():
        stats = _show_capture(view, file, "arcos", "packets", slice(3, -2))  # ARCOS payloads
    if stats is None:
        return
    summary = f"{stats.frames} packets decoded, {stats.dropped_bytes} bytes dropped"
    if stats.frames == 0:
        raise RobocliError(f"{file}: {summary}")
    if stats.dropped_bytes:
        typer.echo(f"robocli: {file}: {summary}", err=True)


def _show_capture(view: Any, file: Path, protocol: str, noun: str,
                  part: slice = slice(None)) -> CaptureStats | None:  # fmt: skip
    """Show each frame of a capture (its ``part`` that ``view`` takes), streamed, until
    ``--count``: None when that ended it, else what the reading found. After
    :data:`~robocli.io.capture.MAX_GAP` bytes without a frame, a :class:`NoFrameError` that
    says how many ``noun`` came before."""
    from robocli.io.capture import CaptureStats, NoFrameError, read_capture

    stats = CaptureStats()
    try:
        for item in read_capture(file, protocol, stats):
            if view.epoch is None:
                view.start(stats.start_unix)  # read before the first frame, when it says
            view.show(item.direction, item.frame[part], item.t)
            if view.done:
                return None
    except NoFrameError as exc:
        raise NoFrameError(
            f"{exc} ({stats.frames} {noun} decoded, {stats.dropped_bytes} bytes dropped)"
        ) from None
    return stats


def _pioneer_live(view: Any, port: str, laser: bool, **options: Any) -> None:
    """Show a live session's packets in time order (sent and received ones come from
    different threads), until Ctrl-C or ``--count``; after Ctrl-C, also the packets that
    stop the robot and close the session."""
    feed = _Feed(view)
    try:
        with connected(port, listeners=[feed.listener()], **options) as robot:
            _begin(view)  # connected: now the capture is made
            if laser:
                start_laser(robot, wait=False)
            while not view.done:
                feed.show()
                if not robot.alive:
                    robot.wait_for_sip(0)  # raises the reason the session ended
    finally:
        with reader_may_leave():
            feed.drain()  # what was still queued, and the close sequence


class _Feed:
    """Packets from the links' reader threads, shown by ``view`` in time order (each waits
    :data:`REORDER` s for older ones from another thread). At most ``bound`` are queued
    (0: no bound); a packet that finds the queue full is lost and counted in ``dropped``:
    a link's reader never waits for a stalled stdout."""

    def __init__(self, view: Any, bound: int = 0) -> None:
        self.view = view
        self.start = time.monotonic()
        view.start(time.time())  # Unix time of t 0, for JSON and a capture being written
        self.queue: queue.Queue[tuple[str, bytes, float]] = queue.Queue(bound)
        self.dropped = 0

    def listener(self, port: str = "") -> Callable[[str, bytes, float], None]:
        """A link's listener ``(direction, frame, t)``; with ``port``, its packets are queued
        as ``"tx:motion"``-style directions."""

        def put(direction: str, frame: bytes, t: float) -> None:
            try:
                self.queue.put_nowait(
                    (f"{direction}:{port}" if port else direction, frame, t - self.start)
                )
            except queue.Full:
                self.dropped += 1

        return put

    def show(self) -> None:
        """Take what comes within :data:`REORDER` s; print what is older than that."""
        self._take(REORDER)
        self.view.flush(before=time.monotonic() - self.start - REORDER)

    def drain(self) -> None:
        """Print everything still queued, in time order."""
        self._take()
        self.view.flush()

    def _take(self, wait: float = 0.0) -> None:
        with contextlib.suppress(queue.Empty):
            if wait:
                self.view.add(*self.queue.get(timeout=wait))
            while True:
                self.view.add(*self.queue.get_nowait())


@arm_link()
def arm(
    ctx: typer.Context,
    host: str | None = typer.Argument(
        None,
        help=f"The arm: {DEVICE_FORMS['arm']}; omit with --file.",
        show_default=False,
        metavar="URL",
        envvar=ARM_ENV,
        show_envvar=True,
    ),
    count: int = typer.Option(0, "--count", "-n", min=0, help="Stop after N messages (0: none)."),
    hex_out: bool = typer.Option(False, "--hex", help="Also print the raw frame bytes."),
    json_out: bool = json_option(),
    output: Path | None = typer.Option(
        None, "--output", "-o", dir_okay=False, help="Also record to a .jsonl capture."
    ),
    overwrite: bool = OverwriteOpt,
    file: Path | None = typer.Option(
        None, "--file", "-f", exists=True, dir_okay=False, help="Decode a capture instead."
    ),
    ports: Literal["both", "motion", "state"] = typer.Option(
        "both", "--ports", help="both (two clients), motion or state."
    ),
    listen: str | None = typer.Option(
        None,
        "--listen",
        metavar="[ADDR:]PORT",
        help="Be a recording proxy: other programs connect to the motion port PORT and the "
        "state port PORT+2 (0: ephemeral) instead of the controller.",
    ),
    link: ArmLink = LINK,
) -> None:
    """Print every Simple Message on the motion and state ports, in time order, named and
    decoded (joints in rad)."""
    from robocli.commands._packets import ArmPacketView
    from robocli.kinematics import load_model

    if file is not None and from_env(ctx, "host"):
        host = None  # $ROBOCLI_ARM names a controller; --file reads a capture instead
    if (host is None) == (file is None):
        raise typer.BadParameter("give HOST or --file (one of them)")
    if ports not in ("both", "motion", "state"):
        raise typer.BadParameter(f"--ports is both, motion or state, not {ports!r}")
    if listen is not None and host is None:
        raise typer.BadParameter("--listen relays to a HOST; not with --file")
    bind_to = _listen_address(listen) if listen is not None else None
    order = ">" if link.byte_order == "big" else "<"
    n = load_model(link.robot).n_joints
    writer = _capture(output, overwrite)
    view = ArmPacketView(order, link.real_size, n, json_out=json_out, hex_out=hex_out,  # type: ignore[arg-type]
                         count=count, writer=writer)  # fmt: skip
    try:
        with reader_may_leave(), sigterm_as_interrupt():
            if file is not None:
                _begin(view)
                _arm_file(view, file, "sm-be" if order == ">" else "sm-le")
            else:
                assert host is not None
                _arm_live(view, host, ports, link, bind_to)
    finally:
        if writer is not None:
            writer.close()


def _arm_file(view: Any, file: Path, protocol: str) -> None:
    """Show the messages of a capture; exit 1 when it holds none, or when
    :data:`~robocli.io.capture.MAX_GAP` bytes come without one (``/dev/zero``)."""
    from robocli.errors import RobocliError

    stats = _show_capture(view, file, protocol, "messages")
    if stats is not None and stats.frames == 0:
        raise RobocliError(f"{file}: no Simple Message frame ({stats.dropped_bytes} bytes "
                           "dropped)")  # fmt: skip


def _listen_address(text: str) -> tuple[str, int]:
    """``--listen [ADDR:]PORT`` -> (address, motion port); the state port is 2 above."""
    from robocli.transports import InvalidURL, parse_address

    try:
        return parse_address(text, None, default_host="127.0.0.1", port_range=(0, 65533))
    except InvalidURL as exc:
        raise typer.BadParameter(
            f"--listen is [ADDR:]PORT with PORT 0 or 1..65533, not {text!r} ({exc.reason})"
        ) from None


def _arm_live(view: Any, host: str, ports: str, link: ArmLink,
              listen: tuple[str, int] | None) -> None:  # fmt: skip
    """Both ports as two clients (or, with ``listen``, as two recording proxies), their
    frames queued by their threads and printed here in time order until ``--count`` or
    Ctrl-C (then what was still queued)."""
    from robocli.devices.arm import Arm
    from robocli.errors import TransportError

    feed = _Feed(view, MAX_QUEUED)  # a stalled stdout loses messages, counted
    with arm_host(host, link.motion_port, link.state_port, link.byte_order, link.real_size,
                  link.robot) as (h, mp, sp), contextlib.ExitStack() as arms:  # fmt: skip
        try:
            state, opened = None, []
            relays = []
            if listen is not None:  # other programs' sessions, through recording proxies
                relays = _relay(arms, feed.listener, (h, mp, sp), ports, listen, link.byte_order)
            for name in () if listen else ("motion", "state") if ports == "both" else (ports,):
                arm = arms.enter_context(Arm.connect(
                    h, mp, sp, motion=name == "motion", state=name == "state",
                    history=16, listeners=[feed.listener(name)], stop_on_failure=False,
                    byte_order=link.byte_order, real_size=link.real_size, robot=link.robot,
                    timeout=link.timeout))  # fmt: skip
                opened.append(arm)
                state = arm if name == "state" else state
            _begin(view)  # connected (or listening): now the capture is made
            while not view.done:
                feed.show()
                for arm in opened:  # raises when a link was lost (the motion port is quiet)
                    arm.check()
                for relay in relays:  # a client came, the controller could not be reached
                    if relay.upstream_error is not None:
                        up, exc = relay.upstream, relay.upstream_error
                        raise TransportError(f"no controller at {up[0]}:{up[1]} "
                                             f"({exc.strerror or exc})")  # fmt: skip
                if state is not None:  # raises when the state link is silent
                    state.wait_for_state(link.timeout)
        finally:
            arms.close()  # nothing is queued after
            feed.drain()
            if feed.dropped:
                typer.echo(f"robocli: {feed.dropped} messages not shown: the output was too slow",
                           err=True)  # fmt: skip


def _relay(stack: contextlib.ExitStack, listener: Any, upstream: tuple[str, int, int],
           ports: str, listen: tuple[str, int], byte_order: str) -> list[Any]:  # fmt: skip
    """Start a recording proxy per port (motion on ``listen``, state 2 above) on ``stack``;
    each frame goes to ``listener(port)("tx"|"rx", frame, t)``. Says where, on stderr.
    The controller is not probed: that would take its one client slot."""
    from robocli.analysis.proxy import Message, RecordingProxy
    from robocli.protocols import simple_message as sm

    def shown(put: Callable[[str, bytes, float], None]) -> Callable[[Message], None]:
        def on_message(m: Message) -> None:
            put("tx" if m.direction == "c2s" else "rx", m.frame, time.monotonic())

        return on_message

    host, mp, sp = upstream
    bind, port = listen
    framer = "sm-be" if byte_order == "big" else "sm-le"
    said, relays = [], []
    for name, offset, target in (("motion", 0, mp), ("state", 2, sp)):
        if ports not in ("both", name):
            continue
        with listening(bind):  # a port in use: exit 1, an address not this machine's: 2
            proxy = RecordingProxy(
                (host, target), shown(listener(name)), framer=framer, max_frame=sm.MAX_FRAME_SIZE,
                bind=bind, port=port + offset if port else 0, max_clients=2,
                name=f"arm-dump-{name}")  # fmt: skip
        stack.enter_context(proxy.start())
        said.append(f"{name} {bind}:{proxy.port} -> {host}:{target}")
        relays.append(proxy)
    typer.echo("dump: clients connect to " + ", ".join(said), err=True)
    return relays


def hub(
    ctx: typer.Context,
    host: str | None = typer.Argument(
        None,
        help=f"The hub: {DEVICE_FORMS['hub']}; omit with --file.",
        show_default=False,
        metavar="URL",
        envvar=HUB_ENV,
        show_envvar=True,
    ),
    listen: str = typer.Option(
        "127.0.0.1:1501", "--listen", help="Where clients connect instead of the hub."
    ),
    count: int = typer.Option(0, "--count", "-n", min=0, help="Stop after N messages (0: none)."),
    hex_out: bool = typer.Option(False, "--hex", help="Also print the raw bytes."),
    json_out: bool = json_option(),
    output: Path | None = typer.Option(
        None, "--output", "-o", help="Also record the session (.jsonl capture)."
    ),
    overwrite: bool = OverwriteOpt,
    file: Path | None = typer.Option(
        None,
        "--file",
        "-f",
        metavar="CAPTURE",
        exists=True,
        dir_okay=False,
        help="Decode a capture (dump hub -o, or a record .mcap) instead.",
    ),
) -> None:
    """A recording proxy: point ros4mat clients at --listen; every message both ways is
    printed, named and decoded, and passed on unchanged. --file decodes a capture."""
    from robocli.commands._packets import HubPacketView

    if file is not None and from_env(ctx, "host"):
        host = None  # $ROBOCLI_HUB names a hub; --file reads a capture instead
    if (host is None) == (file is None):
        raise typer.BadParameter("give HOST or --file (one of them)")
    if output is not None and file is not None and _same_file(output, file):
        raise typer.BadParameter(f"--output {output} is the --file being read: it would be emptied")
    writer = _capture(output, overwrite)  # checked before connecting
    view = HubPacketView(json_out=json_out, hex_out=hex_out, count=count, writer=writer)
    try:
        if file is not None:
            _begin(view)
            with reader_may_leave(), sigterm_as_interrupt():
                stats = _show_capture(view, file, "ros4mat", "messages")
            if stats is not None and stats.frames == 0:
                from robocli.errors import RobocliError

                raise RobocliError(f"{file}: no ros4mat message ({stats.dropped_bytes} bytes "
                                   "dropped)")  # fmt: skip
        else:
            assert host is not None
            _hub_live(view, host, listen)
    finally:
        if writer is not None:
            writer.close()


def _hub_live(view: Any, host: str, listen: str) -> None:
    """Relay ros4mat clients on ``listen`` to the hub at ``host``, each message shown by
    ``view`` from the proxy's threads, until ``--count``, Ctrl-C (exit 130) or ``| head``."""
    import threading

    from robocli.devices.hub.client import parse_hub
    from robocli.analysis.ros4mat import DumpProxy, Message, check_upstream
    from robocli.errors import EXIT_INTERRUPTED
    from robocli.transports import parse_address

    upstream = parse_hub(host)
    bind, port = parse_address(listen, 1501, default_host="127.0.0.1", what="--listen",
                               port_range=(0, 65535))  # fmt: skip
    check_upstream(*upstream)
    done = threading.Event()
    broken = threading.Event()

    def show(msg: Message) -> None:
        if done.is_set():
            return
        view.start(time.time() - msg.t)  # the first message dates the proxy's start
        try:
            view.show("tx" if msg.direction == "c2s" else "rx", msg.frame, msg.t)
        except BrokenPipeError:  # `dump hub ... | head`: the main thread stops quietly
            broken.set()
            done.set()
            return
        if view.done:
            done.set()

    with sigterm_as_interrupt(), reader_may_leave():
        try:
            check_upstream(*upstream)
            with listening(bind):
                proxy = DumpProxy(upstream, show, bind=bind, port=port)
            with proxy.start():
                _begin(view)  # listening: now the capture is made
                typer.echo(
                    f"dump: clients connect to {bind}:{proxy.port}, relayed to "
                    f"{upstream[0]}:{upstream[1]}",
                    err=True,
                )
                while not done.wait(0.25):
                    pass
            if broken.is_set():
                raise BrokenPipeError
        except KeyboardInterrupt:
            raise typer.Exit(EXIT_INTERRUPTED) from None


def _capture(path: Path | None, overwrite: bool) -> Any:
    """A capture writer on ``path`` (JSON Lines), or None: checked now (a name or place it
    cannot have, an existing file without --overwrite, a symbolic link: exit 2, before
    anything connects), made by :func:`_begin` once the session is connected."""
    if path is None:
        return None
    from robocli.io.capture import CaptureWriter

    if path.suffix != ".jsonl":
        raise typer.BadParameter(f"{path}: the capture format needs a .jsonl name",
                                 param_hint="'--output'")  # fmt: skip
    return CaptureWriter(path, overwrite, deferred=True)


def _begin(view: Any) -> None:
    """Make the capture file of ``view`` (if any): its session is connected."""
    if view.writer is not None:
        view.writer.open()
