"""Pioneer benchmarks through the real client code paths: CONFIG round trips (the client,
and a bare socket as the baseline) against a minimal C ARCOS responder or a simulator, and
SIP periods as the client and as a raw socket see them.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from robocli.bench.stats import Progress, Run

REPLY_TIMEOUT_S = 10.0
"""How long a round trip may take before the bench says the robot stopped answering. A slow
reply is a sample of the tail the bench reports (on a busy machine, with client and robot
pinned to one CPU, one took over 2 s); only a reply that never comes ends the run."""

if TYPE_CHECKING:
    from robocli.core import Responder
    from robocli.devices.pioneer import Pioneer

# ---------------------------------------------------------------------------- client RTT


def pioneer_rtt(
    robot: Pioneer, run: Run, warmup: int = 20, progress: Progress | None = None
) -> Run:
    """Fill ``run`` with CONFIG request -> CONFIG reply round trips through ``robot``'s
    :meth:`~robocli.devices.pioneer.Pioneer.request_config` (the caller reads the reply),
    after ``warmup`` unrecorded ones."""
    for _ in range(warmup):
        robot.request_config(timeout=REPLY_TIMEOUT_S)
    clock = time.perf_counter
    samples = run.samples
    while run.count < run.n:
        start = clock()
        robot.request_config(timeout=REPLY_TIMEOUT_S)
        samples[run.count] = clock() - start
        run.count += 1
        if progress is not None and run.count % 256 == 0:
            progress(run.count)
    if progress is not None:
        progress(run.count)
    return run


def bare_rtt(port: int, run: Run, warmup: int = 20, progress: Progress | None = None) -> Run:
    """Fill ``run`` with CONFIG request -> reply round trips of a bare blocking Python
    socket (send, ``recv`` until the C framer has the reply) against a
    :class:`~robocli.core.Responder` on ``port``: what Python costs before any client
    machinery, the baseline that splits a client round trip into its parts."""
    import socket

    from robocli.core import Framer
    from robocli.protocols import arcos
    from robocli.protocols.arcos import Command

    request = arcos.encode_command(Command.CONFIG, 1)
    framer = Framer("arcos")
    clock = time.perf_counter
    with socket.create_connection(("127.0.0.1", port), timeout=5.0) as sock:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        send, recv, feed = sock.sendall, sock.recv, framer.feed
        for i in range(-warmup, run.n):
            start = clock()
            send(request)
            while not feed(recv(4096)):
                pass
            if i >= 0:
                run.samples[i] = clock() - start
                run.count = i + 1
                if progress is not None and run.count % 256 == 0:
                    progress(run.count)
    return run


def arcos_responder_table(name: str = "robocli-bench", subtype: str = "p3dx") -> dict[bytes, bytes]:
    """The canned replies that take a :class:`~robocli.devices.pioneer.Pioneer` through its
    handshake and answer its CONFIG requests: payload of a client frame -> framed reply.

    SYNC0/SYNC1 are echoed, SYNC2 gets ``name\\0type\\0subtype\\0``, OPEN (command 1, int 1)
    gets one SIP (robot at rest at the origin, no sonar), CONFIG (command 18, int 1) gets one
    CONFIG packet. Anything else (PULSE, the stop sequence) gets no reply.
    """
    from robocli.protocols import arcos
    from robocli.protocols.arcos import Command, PacketType

    def payload(frame: bytes) -> bytes:
        return frame[3:-2]

    head = [str(sc.name) for sc in arcos.SIP.subcons]
    sip_body: dict[str, Any] = dict.fromkeys(head[: head.index("sonar")], 0)
    sip_body.update(battery=130, sonar=[])  # 13.0 V; the optional tail groups are left out
    sip = arcos.frame(bytes((PacketType.SIP,)) + arcos.encode_sip_body(sip_body))

    names = [str(sc.name) for sc in arcos.CONFIG.subcons]
    config: dict[str, Any] = dict.fromkeys(names, 0)
    config.update(dict.fromkeys(names[names.index("powerbot_charge_threshold") + 1 :]))
    config.update(
        robot_type="Pioneer", subtype=subtype, serial="BENCH", name=name, firmware="robocli",
        sip_cycle=100, watchdog=2000, ticks_mm=128,
    )  # fmt: skip
    return {
        b"\x00": arcos.frame(b"\x00"),  # SYNC0 (PULSE has the same bytes: echoed too)
        b"\x01": arcos.frame(b"\x01"),  # SYNC1
        b"\x02": arcos.encode_server(  # SYNC2
            PacketType.SYNC2, {"name": name, "type": "Pioneer", "subtype": subtype}
        ),
        payload(arcos.encode_command(Command.OPEN, 1)): sip,
        payload(arcos.encode_command(Command.CONFIG, 1)): arcos.encode_server(
            PacketType.CONFIG, config
        ),
    }


@contextlib.contextmanager
def arcos_responder(cpu: int | None = None) -> Iterator[Responder]:
    """A C ARCOS responder (:func:`arcos_responder_table`) on loopback, its thread pinned to
    ``cpu``; stopped (bounded) when the block ends."""
    from robocli.core import Responder

    with Responder(arcos_responder_table(), cpu=cpu) as responder:
        yield responder


@contextlib.contextmanager
def pioneer_on_responder(responder: Responder, timeout: float = 5.0) -> Iterator[Pioneer]:
    """The real client, handshake included, connected to ``responder``. The responder sends
    a single SIP, so the SIP watchdog is set to an hour."""
    from robocli.devices.pioneer import Pioneer
    from robocli.transports import SocketTransport

    transport = SocketTransport.connect("127.0.0.1", responder.port, timeout=timeout)
    with Pioneer.from_transport(transport, timeout=timeout, sip_timeout=3600.0) as robot:
        yield robot


@contextlib.contextmanager
def pioneer_at(url: str) -> Iterator[Pioneer]:
    """The real client connected to ``url`` (a robot, or a simulator in another process)."""
    from robocli.devices.pioneer import Pioneer

    with Pioneer.connect(url) as robot:
        yield robot


# ---------------------------------------------------------------------------- SIP timing


def pioneer_sip_timing(
    url: str,
    n: int = 300,
    progress: Progress | None = None,
    into: dict[str, npt.NDArray[np.float64]] | None = None,
) -> dict[str, npt.NDArray[np.float64]]:
    """Collect ``n`` SIPs: their periods, the client work per SIP and keep-alive periods.

    The arrays are also written into ``into`` (when given) on every way out, so a run stopped
    by Ctrl-C still hands back what it collected.
    """
    from robocli.devices.pioneer import Pioneer

    out: dict[str, npt.NDArray[np.float64]] = {} if into is None else into
    with Pioneer.connect(url) as robot:
        first = robot.stats.sips
        try:
            while (got := robot.stats.sips - first) < n + 1:
                robot.wait_for_sip(timeout=robot.sip_timeout)
                if progress is not None:
                    progress(max(0, got))
        finally:
            taken = min(n + 1, robot.stats.sips - first)
            sip_times = np.array(robot.stats.sip_times, dtype=np.float64)
            sip_times = sip_times[len(sip_times) - taken :] if taken > 0 else sip_times[:0]
            work = np.array(robot.stats.sip_work, dtype=np.float64)
            out["period"] = np.diff(sip_times)
            out["work"] = work[len(work) - max(0, taken - 1) :] if taken > 1 else work[:0]
            out["keepalive"] = np.diff(np.array(robot.stats.keepalive_times, dtype=np.float64))
    return out


def raw_sip_periods(host: str, port: int, n: int = 200, timeout: float = 5.0) -> Run:
    """SIP periods as a bare reader sees them: a plain socket, the C framer, a monotonic
    stamp per SIP and nothing else (SYNC0/1/2 and OPEN sent blindly, then PULSE every
    0.5 s), so the figure is the server's own cycle. ``n`` periods; every wait bounded."""
    import socket

    from robocli import errors
    from robocli.core import Framer
    from robocli.protocols import arcos
    from robocli.protocols.arcos import Command

    run = Run("SIP period, raw socket reader", n, f"tcp://{host}:{port}")
    framer = Framer("arcos")
    stamps: list[float] = []
    with socket.create_connection((host, port), timeout=timeout) as sock:
        for step in (0, 1, 2):
            sock.sendall(arcos.encode_command(step))
            time.sleep(0.05)
        sock.sendall(arcos.encode_command(Command.OPEN, 1))
        pulse_at = time.monotonic() + 0.5
        try:
            while len(stamps) < n + 1:
                data = sock.recv(4096)
                now = time.monotonic()
                if not data:
                    break
                stamps.extend(now for f in framer.feed(data) if f[3] & 0xF0 == 0x30)
                if now >= pulse_at:
                    sock.sendall(arcos.encode_command(Command.PULSE))
                    pulse_at = now + 0.5
        except TimeoutError:  # the socket's
            raise errors.TimeoutError(f"no SIP from {host}:{port} within {timeout:g} s") from None
        finally:
            with contextlib.suppress(OSError):
                sock.sendall(arcos.encode_command(Command.CLOSE, 1))
            periods = np.diff(np.array(stamps[: n + 1], dtype=np.float64))
            run.samples[: periods.size] = periods
            run.count = int(periods.size)
    return run
