"""Captures and live sessions as packets in time order: what ``robocli dump`` reads.

:func:`read_packets` streams a capture file's packets (a notebook's entry point);
:func:`replay_capture` hands them to a :class:`~robocli.analysis.packets.PacketLog` and says
when a file holds none. For live sessions, the links' listeners are a log's
(:meth:`~robocli.analysis.packets.PacketLog.listener`), :func:`arm_clients` and
:func:`arm_relays` open an arm's ports as clients or as recording proxies, :func:`hub_proxy`
relays ros4mat clients to a hub, and the ``*_check`` functions raise when a link ended;
:func:`arm_session` and :func:`hub_session` follow a whole live session into a log.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from robocli.analysis.packets import Decode, Packet, PacketLog
from robocli.errors import RobocliError
from robocli.running import listening

if TYPE_CHECKING:
    from robocli.analysis.proxy import Message, RecordingProxy
    from robocli.analysis.ros4mat import DumpProxy
    from robocli.devices.arm import Arm
    from robocli.devices.laser import Laser
    from robocli.devices.pioneer import Pioneer
    from robocli.io.capture import CaptureStats

__all__ = [
    "arm_check", "arm_clients", "arm_relays", "arm_session", "decoder", "hub_proxy",
    "hub_session", "laser_check", "pioneer_check", "read_packets", "replay_capture",
]  # fmt: skip

#: What a capture's frames are called in messages, by protocol.
NOUNS = {"arcos": "packets", "scip2": "blocks"}
#: What a capture without a frame of the protocol is said to hold none of.
_NONE = {"sm-le": "Simple Message frame", "sm-be": "Simple Message frame",
         "ros4mat": "ros4mat message", "scip2": "SCIP line decoded"}  # fmt: skip


def decoder(protocol: str, **options: Any) -> Decode:
    """A new decoder for ``protocol``: ``arcos``, ``sm-le``/``sm-be`` (``n_joints``,
    ``real``), ``ros4mat`` or ``scip2``."""
    if protocol == "arcos":
        from robocli.analysis.arcos import ArcosDecoder

        return ArcosDecoder()
    if protocol in ("sm-le", "sm-be"):
        from robocli.analysis.simple_message import SimpleMessageDecoder

        return SimpleMessageDecoder(">" if protocol == "sm-be" else "<", **options)
    if protocol == "ros4mat":
        from robocli.analysis.ros4mat import decode_packet

        return decode_packet
    if protocol == "scip2":
        from robocli.analysis.scip import decode_packet as decode_scip

        return decode_scip
    raise RobocliError(f"no decoder for {protocol!r}")


def read_packets(path: str | Path, protocol: str, decode: Decode | None = None,
                 stats: CaptureStats | None = None,
                 on_start: Callable[[float], None] | None = None) -> Iterator[Packet]:  # fmt: skip
    """The packets of a capture (``dump --output``'s ``.jsonl``, a recording's raw
    channels, raw bytes), named and decoded by ``decode`` (default: :func:`decoder`),
    streamed. ``stats`` counts frames and dropped bytes as it goes; ``on_start`` is told the
    Unix time of ``t`` 0 when the file says it. Too many bytes without a frame raise
    :class:`~robocli.io.capture.NoFrameError`, saying how many came before."""
    from robocli.io.capture import CaptureStats, NoFrameError, read_capture

    decode = decoder(protocol) if decode is None else decode
    stats = CaptureStats() if stats is None else stats
    if protocol == "scip2":
        yield from _scip_packets(Path(path), decode, stats, on_start)
        return
    part = slice(3, -2) if protocol == "arcos" else slice(None)  # ARCOS: the payloads
    try:
        for item in read_capture(path, protocol, stats):
            if on_start is not None and stats.start_unix is not None:
                on_start(stats.start_unix)
            yield decode(item.direction, item.frame[part], item.t)
    except NoFrameError as exc:
        raise NoFrameError(f"{exc} ({stats.frames} {NOUNS.get(protocol, 'messages')} "
                           f"decoded, {stats.dropped_bytes} bytes dropped)") from None  # fmt: skip


def _scip_packets(path: Path, decode: Decode, stats: CaptureStats,
                  on_start: Callable[[float], None] | None) -> Iterator[Packet]:  # fmt: skip
    from robocli.analysis.scip import ScipCapture

    capture = ScipCapture(path, on_start)
    try:
        for t, direction, frame in capture:
            yield decode(direction, frame, t)
    finally:
        stats.frames, stats.dropped_bytes = capture.frames, capture.dropped_bytes


def replay_capture(log: PacketLog, path: Path, protocol: str) -> CaptureStats | None:
    """Hand the packets of a capture to ``log`` until its count: None when that ended it,
    else what the reading found. A file without a frame raises :class:`RobocliError`
    (a recording's laser channels excepted: a recording may hold none)."""
    from robocli.io.capture import CaptureStats

    stats = CaptureStats()
    for packet in read_packets(path, protocol, log.decode, stats, log.start):
        log.put(packet)
        if log.done:
            return None
    if stats.frames == 0 and not (protocol == "scip2" and path.suffix == ".mcap"):
        dropped = f"{stats.dropped_bytes} bytes dropped"
        raise RobocliError(f"{path}: {stats.frames} packets decoded, {dropped}"
                           if protocol == "arcos" else
                           f"{path}: no {_NONE[protocol]} ({dropped})")  # fmt: skip
    return stats


def pioneer_check(robot: Pioneer) -> Callable[[], None]:
    """Raises the reason ``robot``'s session ended, once it did."""

    def check() -> None:
        if not robot.alive:
            robot.wait_for_sip(0)

    return check


def laser_check(log: PacketLog, laser: Laser, count: int) -> None:
    """Stream ``laser``'s scans (MD) until ``count`` of them (0: until Ctrl-C), raising
    what the log's ``emit`` raised in the link's thread (its listener: ``log.direct``)."""
    with contextlib.closing(laser.scans(None)) as scans:  # QT now, not at collection
        for n, _ in enumerate(scans, 1):
            log.check()
            if count and n >= count:
                break


def arm_clients(stack: contextlib.ExitStack, log: PacketLog, address: tuple[str, int, int],
                ports: str, **link: Any) -> list[Arm]:  # fmt: skip
    """Open an arm's motion and state ports (``ports``: both, motion or state) as clients
    on ``stack``, every frame to ``log`` as ``"tx:motion"``-style directions; ``link``:
    :meth:`Arm.connect <robocli.devices.arm.Arm.connect>`'s byte order, real size, robot,
    timeout. The state client is last."""
    from robocli.devices.arm import Arm

    opened = []
    for name in ("motion", "state") if ports == "both" else (ports,):
        opened.append(stack.enter_context(Arm.connect(
            *address, motion=name == "motion", state=name == "state", history=16,
            listeners=[log.listener(name)], stop_on_failure=False, **link)))  # fmt: skip
    return opened


def arm_relays(stack: contextlib.ExitStack, log: PacketLog, upstream: tuple[str, int, int],
               ports: str, listen: tuple[str, int],
               byte_order: str) -> list[RecordingProxy]:  # fmt: skip
    """A recording proxy per port of ``ports`` on ``stack`` (motion on ``listen``, state 2
    above; port 0: ephemeral), each frame to ``log`` as for :func:`arm_clients`. The
    controller is not probed: that would take its one client slot."""
    from robocli.analysis.proxy import RecordingProxy
    from robocli.protocols import simple_message as sm

    def shown(put: Callable[[str, bytes, float], None]) -> Callable[[Message], None]:
        def on_message(m: Message) -> None:
            put("tx" if m.direction == "c2s" else "rx", m.frame, time.monotonic())

        return on_message

    host, mp, sp = upstream
    bind, port = listen
    relays = []
    for name, offset, target in (("motion", 0, mp), ("state", 2, sp)):
        if ports in ("both", name):
            proxy = RecordingProxy(
                (host, target), shown(log.listener(name)), framer=f"sm-{byte_order[0]}e",
                max_frame=sm.MAX_FRAME_SIZE, bind=bind, port=port + offset if port else 0,
                max_clients=2, name=f"arm-dump-{name}")  # fmt: skip
            relays.append(stack.enter_context(proxy.start()))
    return relays


def arm_check(arms: list[Arm], relays: list[RecordingProxy], ports: str,
              timeout: float) -> Callable[[], None]:  # fmt: skip
    """Raises when a client's link was lost, when a relay's controller could not be
    reached, or when the state link (the last client, unless ``ports`` is motion) is silent
    for ``timeout`` s."""
    from robocli.errors import TransportError

    def check() -> None:
        for arm in arms:
            arm.check()
        for relay in relays:  # a client came, the controller could not be reached
            if relay.upstream_error is not None:
                (host, port), exc = relay.upstream, relay.upstream_error
                raise TransportError(f"no controller at {host}:{port} ({exc.strerror or exc})")
        if arms and ports != "motion":
            arms[-1].wait_for_state(timeout)

    return check


def hub_proxy(log: PacketLog, upstream: tuple[str, int], bind: str, port: int) -> DumpProxy:
    """A recording proxy on ``bind:port`` relaying ros4mat clients to the hub at
    ``upstream``, each message handed to ``log`` from the proxy's threads, in order (the
    first dates ``t`` 0); once ``log`` stopped, the rest are only relayed."""
    from robocli.analysis.ros4mat import DumpProxy

    def show(msg: Message) -> None:
        log.start(time.time() - msg.t)
        log.direct("tx" if msg.direction == "c2s" else "rx", msg.frame, msg.t)

    return DumpProxy(upstream, show, bind=bind, port=port)


def arm_session(log: PacketLog, address: tuple[str, int, int], ports: str, *,
                listen: tuple[str, int] | None = None, timeout: float = 5.0,
                on_relays: Callable[[str], None] = lambda text: None,
                **wire: Any) -> None:  # fmt: skip
    """Follow the arm at ``(host, motion port, state port)`` into ``log`` until a link ends
    or ``log`` has its count: as a client of each port of ``ports`` (``wire``: byte_order,
    real_size, robot), or with ``listen`` (address, motion port) as recording proxies other
    programs connect to (``on_relays`` is told where, in one line). ``log`` is opened once
    connected or listening (a capture being written is made then), drained and closed
    however the session ends."""
    with contextlib.ExitStack() as stack:
        arms: list[Arm] = []
        relays: list[RecordingProxy] = []
        try:
            if listen is not None:
                with listening(listen[0]):  # in use: exit 1; not this machine's: 2
                    relays = arm_relays(stack, log, address, ports, listen, wire["byte_order"])
                names = [n for n in ("motion", "state") if ports in ("both", n)]
                on_relays("clients connect to " + ", ".join(
                    f"{n} {listen[0]}:{r.port} -> {r.upstream[0]}:{r.upstream[1]}"
                    for n, r in zip(names, relays, strict=True)))  # fmt: skip
            else:
                arms = arm_clients(stack, log, address, ports, timeout=timeout, **wire)
            log.open()
            log.follow(arm_check(arms, relays, ports, timeout))
        finally:
            stack.close()  # nothing is queued after
            log.drain()
            log.close()


def hub_session(log: PacketLog, upstream: tuple[str, int], bind: str, port: int,
                on_listening: Callable[[int], None] = lambda port: None) -> None:  # fmt: skip
    """Relay ros4mat clients from ``bind:port`` to the hub at ``upstream``
    (:func:`hub_proxy`), ``log`` opened once listening (``on_listening`` told the port),
    until ``log`` stopped; then raise what the proxy's threads met."""
    from robocli.analysis.ros4mat import check_upstream

    check_upstream(*upstream)
    with listening(bind):
        proxy = hub_proxy(log, upstream, bind, port)
    with proxy.start():
        log.open()
        on_listening(proxy.port)
        while not log.stopped.wait(0.25):
            pass
    log.check()  # `dump hub ... | head`: what the proxy's thread met, said here
