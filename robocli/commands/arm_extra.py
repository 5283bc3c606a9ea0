"""``robocli dump arm``: a thin layer over :class:`robocli.devices.arm.Arm`.

The dump opens the motion and the state port as two clients (``--ports`` picks one; an ABB
takes one client per port, so a dump holding the motion port keeps others from uploading)
and shows every Simple Message both ways, in time order, named and decoded. ``--file``
decodes a ``.jsonl`` capture (what ``--output`` records, or a trace) instead.
"""

from __future__ import annotations

import contextlib
import json
import queue
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import typer

from robocli.commands._common import (
    from_env,
    listening,
    reader_may_leave,
    rounded,
    sigterm_as_interrupt,
)
from robocli.commands.arm import (
    ByteOrder,
    MotionPortOpt,
    OrderOpt,
    RealOpt,
    RealSize,
    RobotOpt,
    StatePortOpt,
    TimeoutOpt,
    arm_host,
    check_wire,
)
from robocli.defaults import ARM_ENV

if TYPE_CHECKING:
    from robocli.protocols import simple_message as sm

HostArg = typer.Argument(..., help="Controller address, or 'sim' for an embedded simulator.",
                         show_default=False, metavar="HOST", envvar=ARM_ENV,
                         show_envvar=True)  # fmt: skip
_ARROWS = {"tx": "->", "rx": "<-"}
_SEQ = {-1: "start", -2: "stream", -3: "end", -4: "STOP"}
#: Short names in text lines (JSON keeps the protocol's names).
_SHORT = {"drives_powered": "powered", "e_stopped": "estop", "error_code": "code",
          "in_error": "error", "in_motion": "moving", "motion_possible": "possible",
          "valid_fields": "valid", "sequence": "seq", "robot_id": "robot"}  # fmt: skip
_VALID_BITS = {"time": 1, "positions": 2, "velocities": 4, "accelerations": 8}
#: Messages queued for the output at most (bounded memory when stdout stalls).
MAX_QUEUED = 20_000
#: How long a message waits for older ones from the other port's thread (s).
_REORDER = 0.05


def describe(frame: bytes, order: sm.ByteOrder = "<", real: sm.RealSize = 4,
             n_joints: int = 6) -> tuple[str, dict[str, Any]]:  # fmt: skip
    """Name and decoded fields of one whole Simple Message frame (joints cut to
    ``n_joints``). A frame that does not decode is named ``undecodable`` with the reason."""
    from robocli.errors import FramingError, ProtocolError
    from robocli.protocols import simple_message as sm
    from robocli.protocols.simple_message import CommType, MsgType, ReplyCode

    try:
        msg = sm.decode(frame, byteorder=order, real=real)
    except (FramingError, ProtocolError) as exc:
        return "undecodable", {"error": str(exc)}
    name = msg.msg_type.name if isinstance(msg.msg_type, MsgType) else f"TYPE_{msg.msg_type}"
    if msg.comm_type == CommType.SERVICE_REQUEST:
        name += " req"
    elif msg.comm_type == CommType.SERVICE_REPLY:
        code = msg.reply_code
        name += " " + (code.name if isinstance(code, ReplyCode) else f"reply {code}")
    body = msg.body
    if not isinstance(body, dict):
        return name, ({"bytes": len(body)} if isinstance(body, bytes) and body else {})
    valid = body.get("valid_fields")
    fields: dict[str, Any] = {}
    for key, value in body.items():
        if valid is not None and key in _VALID_BITS and not valid & _VALID_BITS[key]:
            continue  # JOINT_FEEDBACK / JOINT_TRAJ_PT_FULL: only the fields it says are valid
        if isinstance(value, list):
            value = value[:n_joints]
        if key == "sequence" and value in _SEQ:
            value = f"{value}({_SEQ[value]})"
        fields[key] = value
    return name, fields


def packet_view(order: sm.ByteOrder, real: sm.RealSize, n_joints: int, **options: Any) -> Any:
    """A :class:`~robocli.commands._packets.PacketView` (its time ordering and ``--count``)
    that shows Simple Message frames; each queued direction is ``"tx:motion"``-style
    (direction and port). Built on first use, so that ``robocli --help`` stays fast."""
    from robocli.commands._packets import LINE_MAX, PacketView, ellipsis

    class ArmPacketView(PacketView):
        def show(self, direction: str, payload: bytes, t: float | None) -> None:
            """Print one frame now (``payload``: the whole frame, ``direction``: dir:port)."""
            way, _, port = direction.partition(":")
            name, fields = describe(payload, order, real, n_joints)
            if self.writer is not None:
                self.writer.write(t or 0.0, way, payload)
            if self.json_out:
                record = {"t": t, "port": port or None, "dir": way, "name": name,
                          "fields": fields}  # fmt: skip
                if self.hex_out:
                    record["hex"] = payload.hex()
                sys.stdout.write(json.dumps(rounded(record), default=str) + "\n")
            else:
                text = " ".join(f"{_SHORT.get(k, k)}={_short(v)}" for k, v in fields.items())
                stamp = f"{t:9.3f} " if t is not None else ""
                line = f"{stamp}{port or '-':<6} {_ARROWS.get(way, '  ')} {name:<22} {text}"
                line = line.rstrip()
                mark = ellipsis()
                cut = line if len(line) <= LINE_MAX else line[: LINE_MAX - len(mark)] + mark
                sys.stdout.write(cut + "\n")
                if self.hex_out:
                    sys.stdout.write(f"{'':13}{payload.hex(' ')}\n")
            sys.stdout.flush()
            self.printed += 1

    return ArmPacketView(**options)


def _short(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, list):
        return "[" + ",".join(_short(v) for v in value) + "]"
    return str(value)


def dump(
    ctx: typer.Context,
    host: str | None = typer.Argument(  # noqa: UP007
        None, help="Controller address, 'sim' for an embedded simulator; omit with --file.",
        show_default=False, metavar="HOST", envvar=ARM_ENV, show_envvar=True,
    ),  # fmt: skip
    count: int = typer.Option(0, "--count", "-n", min=0, help="Stop after N messages (0: none)."),
    hex_out: bool = typer.Option(False, "--hex", help="Also print the raw frame bytes."),
    json_out: bool = typer.Option(False, "--json", help="One JSON object per message."),
    output: Path | None = typer.Option(  # noqa: UP007
        None, "--output", "-o", dir_okay=False, help="Also record to a .jsonl capture."
    ),
    file: Path | None = typer.Option(  # noqa: UP007
        None, "--file", "-f", exists=True, dir_okay=False, help="Decode a capture instead."
    ),
    ports: Literal["both", "motion", "state"] = typer.Option(
        "both", "--ports", help="both (two clients), motion or state."
    ),
    listen: str | None = typer.Option(  # noqa: UP007
        None, "--listen", metavar="[ADDR:]PORT",
        help="Be a recording proxy: other programs connect to the motion port PORT and the "
        "state port PORT+2 (0: ephemeral) instead of the controller.",
    ),  # fmt: skip
    motion_port: int = MotionPortOpt,
    state_port: int = StatePortOpt,
    byte_order: ByteOrder = OrderOpt,
    real_size: RealSize = RealOpt,
    robot: str = RobotOpt,
    timeout: float = TimeoutOpt,
) -> None:
    """Print every Simple Message on the motion and state ports, in time order, named and
    decoded (joints in rad)."""
    from robocli.io.capture import CaptureWriter
    from robocli.kinematics import load_model

    check_wire(byte_order, real_size)
    if file is not None and from_env(ctx, "host"):
        host = None  # $ROBOCLI_ARM names a controller; --file reads a capture instead
    if (host is None) == (file is None):
        raise typer.BadParameter("give HOST or --file (one of them)")
    if ports not in ("both", "motion", "state"):
        raise typer.BadParameter(f"--ports is both, motion or state, not {ports!r}")
    if listen is not None and host is None:
        raise typer.BadParameter("--listen relays to a HOST; not with --file")
    bind_to = _listen_address(listen) if listen is not None else None
    if output is not None and output.suffix != ".jsonl":
        raise typer.BadParameter(f"--output {output}: the capture format needs a .jsonl name")
    order = ">" if byte_order == "big" else "<"
    n = load_model(robot).n_joints
    writer = CaptureWriter(output) if output is not None else None
    view = packet_view(order, real_size, n, json_out=json_out, hex_out=hex_out,  # type: ignore[arg-type]
                       count=count, writer=writer)  # fmt: skip
    try:
        with reader_may_leave(), sigterm_as_interrupt():
            if file is not None:
                _dump_file(view, file, "sm-be" if order == ">" else "sm-le")
            else:
                assert host is not None
                _dump_live(view, host, ports, (motion_port, state_port),
                           dict(byte_order=byte_order, real_size=real_size, robot=robot,
                                timeout=timeout), bind_to)  # fmt: skip
    finally:
        if writer is not None:
            writer.close()


def _dump_file(view: Any, file: Path, protocol: str) -> None:
    """Show the messages of a capture; exit 1 when it holds none, or when
    :data:`~robocli.io.capture.MAX_GAP` bytes come without one (``/dev/zero``)."""
    from robocli.errors import RobocliError
    from robocli.io.capture import CaptureStats, NoFrameError, read_capture

    stats = CaptureStats()
    try:
        for item in read_capture(file, protocol, stats):
            view.show(item.direction, item.frame, item.t)
            if view.done:
                return
    except NoFrameError as exc:
        raise NoFrameError(
            f"{exc} ({stats.frames} messages decoded, {stats.dropped_bytes} bytes dropped)"
        ) from None
    if stats.frames == 0:
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


def _dump_live(view: Any, host: str, ports: str, port_numbers: tuple[int, int],
               options: dict[str, Any], listen: tuple[str, int] | None) -> None:  # fmt: skip
    """Both ports as two clients (or, with ``listen``, as two recording proxies), their
    frames queued by their threads and printed here in time order until ``--count`` or
    Ctrl-C (then what was still queued)."""
    from robocli.devices.arm import Arm
    from robocli.errors import TransportError

    start = time.monotonic()
    seen: queue.Queue[tuple[str, bytes, float]] = queue.Queue(MAX_QUEUED)
    dropped = [0]

    def listener(port: str) -> Any:
        def put(way: str, frame: bytes, t: float) -> None:
            try:  # never block a link's reader: a stalled stdout loses messages, counted
                seen.put_nowait((f"{way}:{port}", frame, t - start))
            except queue.Full:
                dropped[0] += 1

        return put

    def take(wait: float = 0.0) -> None:
        with contextlib.suppress(queue.Empty):
            if wait:
                view.add(*seen.get(timeout=wait))
            while True:
                view.add(*seen.get_nowait())

    with arm_host(host, *port_numbers, options["byte_order"], options["real_size"],
                  options["robot"]) as (h, mp, sp), contextlib.ExitStack() as arms:  # fmt: skip
        try:
            state, opened = None, []
            relays = []
            if listen is not None:  # other programs' sessions, through recording proxies
                relays = _relay(arms, listener, (h, mp, sp), ports, listen, options["byte_order"])
            for name in () if listen else ("motion", "state") if ports == "both" else (ports,):
                arm = arms.enter_context(Arm.connect(
                    h, mp, sp, motion=name == "motion", state=name == "state",
                    history=16, listeners=[listener(name)], stop_on_failure=False,
                    **options))  # fmt: skip
                opened.append(arm)
                state = arm if name == "state" else state
            while not view.done:
                take(_REORDER)
                view.flush(before=time.monotonic() - start - _REORDER)
                for arm in opened:  # raises when a link was lost (the motion port is quiet)
                    arm.check()
                for relay in relays:  # a client came, the controller could not be reached
                    if relay.upstream_error is not None:
                        up, exc = relay.upstream, relay.upstream_error
                        raise TransportError(f"no controller at {up[0]}:{up[1]} "
                                             f"({exc.strerror or exc})")  # fmt: skip
                if state is not None:  # raises when the state link is silent
                    state.wait_for_state(options["timeout"])
        finally:
            arms.close()  # nothing is queued after
            take()
            view.flush()
            if dropped[0]:
                typer.echo(f"robocli: {dropped[0]} messages not shown: the output was too slow",
                           err=True)  # fmt: skip


def _relay(stack: contextlib.ExitStack, listener: Any, upstream: tuple[str, int, int],
           ports: str, listen: tuple[str, int], byte_order: str) -> list[Any]:  # fmt: skip
    """Start a recording proxy per port (motion on ``listen``, state 2 above) on ``stack``;
    each frame goes to ``listener(port)("tx"|"rx", frame, t)``. Says where, on stderr.
    The controller is not probed: that would take its one client slot."""
    from robocli.devices.proxy import Message, RecordingProxy
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
