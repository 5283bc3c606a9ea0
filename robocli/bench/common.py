"""Latency, jitter and per-packet cost, measured through the real client code paths.

Statistics follow the IRB120 paper's Table 5 (n, mean, median, std, min, max) plus p90/p99,
and every latency is also given as a multiple of the machine's floor: a C ping-pong over
loopback TCP measured in the same run (:class:`robocli.core.PingPong`) with **both ends
pinned to one CPU**, so figures mean the same on any machine (unpinned, the two ends land on
one CPU or on two from run to run, and the floor changes by an order of magnitude).

Every measurement fills a :class:`Run` as it goes, so a run stopped by Ctrl-C keeps what it
collected; long loops call a ``progress(done)`` callback. All samples are in seconds.
"""

from __future__ import annotations

import contextlib
import math
import os
import selectors
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from robocli.core import Responder
    from robocli.devices.pioneer import Pioneer

Progress = Callable[[int], None]
#: Longest a single C call of the floor may last (seconds), so Ctrl-C is seen quickly.
CHUNK_SECONDS = 0.1
#: Largest number of round trips in one C call of the floor.
MAX_CHUNK = 10_000


@dataclass(frozen=True)
class Stats:
    """Table-5 statistics of a sample set (seconds, or whatever unit the samples are in)."""

    n: int
    mean: float
    median: float
    std: float
    min: float
    max: float
    p90: float
    p99: float

    @classmethod
    def of(cls, samples: npt.ArrayLike) -> Stats:
        a = np.asarray(samples, dtype=np.float64)
        if a.size == 0:
            raise ValueError("no samples")
        p50, p90, p99 = np.percentile(a, [50, 90, 99])
        return cls(
            n=int(a.size),
            mean=float(a.mean()),
            median=float(p50),
            std=float(a.std(ddof=1)) if a.size > 1 else 0.0,
            min=float(a.min()),
            max=float(a.max()),
            p90=float(p90),
            p99=float(p99),
        )

    def as_dict(self, scale: float = 1.0) -> dict[str, float]:
        """Fields as a dict, values multiplied by ``scale`` (``n`` untouched)."""
        return {k: (v if k == "n" else v * scale) for k, v in asdict(self).items()}


@dataclass
class Run:
    """One measurement being collected: up to ``n`` samples, ``count`` of them taken so far.

    ``where`` says on which CPUs the ends ran (e.g. ``"client CPU 0, responder CPU 0"``).
    """

    name: str
    n: int
    where: str = ""
    samples: npt.NDArray[np.float64] = field(init=False, repr=False)
    count: int = 0

    def __post_init__(self) -> None:
        if self.n <= 0:
            raise ValueError("n must be positive")
        self.samples = np.empty(self.n, dtype=np.float64)

    @property
    def values(self) -> npt.NDArray[np.float64]:
        """The samples taken so far."""
        return self.samples[: self.count]

    @property
    def complete(self) -> bool:
        return self.count == self.n


def histogram(
    samples: npt.ArrayLike, bins: int = 12, width: int = 40, unit: float = 1e-6, label: str = "us"
) -> list[str]:
    """A text histogram: one line per bin, ``[lo, hi) count bar``."""
    a = np.asarray(samples, dtype=np.float64) / unit
    if a.size == 0:
        return []
    lo, hi = float(a.min()), float(a.max())
    if hi == lo:
        hi = lo + 1.0
    counts, edges = np.histogram(a, bins=bins, range=(lo, hi))
    top = max(int(counts.max()), 1)
    # enough decimals that neighbouring edges differ (a 0.02 ms spread: 99.91 - 99.93)
    digits = min(6, max(1, 1 - math.floor(math.log10((hi - lo) / bins))))
    return [
        f"{edges[i]:10.{digits}f} - {edges[i + 1]:10.{digits}f} {label} {int(c):7d} "
        + "#" * max(int(c) and 1, round(width * int(c) / top))
        for i, c in enumerate(counts)
    ]


@contextlib.contextmanager
def child_process(
    code: str, *args: str, timeout: float = 20.0
) -> Iterator[tuple[subprocess.Popen[str], str]]:
    """A Python child running ``code`` (``args`` as its argv), stdin and stdout piped, in its
    own session (a Ctrl-C reaches only us; we stop it). Yields it and the first line it
    printed within ``timeout`` s ("" if none). On the way out: the end of its stdin (children
    wait for it: :func:`wait_for_stdin_eof`), then SIGTERM, then SIGKILL, 1 s each."""
    proc = subprocess.Popen(
        [sys.executable, "-c", code, *args], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
        text=True, start_new_session=True,
    )  # fmt: skip
    try:
        yield proc, read_line(proc, timeout)
    finally:
        with contextlib.suppress(OSError):
            if proc.stdin is not None:
                proc.stdin.close()
        for stop in (None, proc.terminate, proc.kill):
            if stop is not None:
                stop()
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.wait(1.0)
                break
        if proc.stdout is not None:
            proc.stdout.close()


def read_line(proc: subprocess.Popen[str], timeout: float) -> str:
    """The next line a child prints within ``timeout`` s, stripped ("" if none)."""
    assert proc.stdout is not None
    with selectors.DefaultSelector() as sel:
        sel.register(proc.stdout, selectors.EVENT_READ)
        ready = sel.select(timeout)
    return proc.stdout.readline().strip() if ready else ""


def wait_for_stdin_eof() -> None:
    """Block until standard input ends: how a benchmark's child process learns that its
    parent is done (or gone). Reads in fixed chunks, so a chatty parent costs no memory."""
    while sys.stdin.buffer.read(4096):
        pass


# ---------------------------------------------------------------------------- CPUs


def allowed_cpus() -> list[int]:
    """CPUs this process may run on (empty where the platform cannot pin threads)."""
    from robocli.core import pin_supported

    if not pin_supported() or not hasattr(os, "sched_getaffinity"):
        return []
    return sorted(os.sched_getaffinity(0))


@contextlib.contextmanager
def pinned(cpu: int | None) -> Iterator[None]:
    """Pin the calling thread to ``cpu`` (None: leave it) for the block, then restore its
    affinity. Threads started inside the block inherit the pinning (Linux)."""
    if cpu is None or not hasattr(os, "sched_setaffinity"):
        yield
        return
    before = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {cpu})
    try:
        yield
    finally:
        os.sched_setaffinity(0, before)


def cpu_label(cpu: int | None) -> str:
    return "unpinned" if cpu is None else f"CPU {cpu}"


# ---------------------------------------------------------------------------- C floor


def c_floor(
    run: Run,
    cpu: int | None = None,
    echo_cpu: int | None = None,
    msg_size: int = 16,
    progress: Progress | None = None,
) -> Run:
    """Fill ``run`` with C ping-pong round trips, the caller's end on ``cpu`` and the echo
    thread on ``echo_cpu``. Runs in chunks of at most :data:`CHUNK_SECONDS` (and
    :data:`MAX_CHUNK` round trips) so Ctrl-C stops it between two chunks."""
    from robocli.core import PingPong

    with PingPong(msg_size, echo_cpu) as pp:
        chunk = 200
        while run.count < run.n:
            k = min(chunk, run.n - run.count)
            start = time.perf_counter()
            run.samples[run.count : run.count + k] = pp.run(k, cpu)
            run.count += k
            took = max(time.perf_counter() - start, 1e-6)
            chunk = max(50, min(MAX_CHUNK, int(k * CHUNK_SECONDS / took)))
            if progress is not None:
                progress(run.count)
    return run


# ---------------------------------------------------------------------------- client RTT


def pioneer_rtt(
    robot: Pioneer, run: Run, warmup: int = 20, progress: Progress | None = None
) -> Run:
    """Fill ``run`` with CONFIG request -> CONFIG reply round trips through ``robot``'s
    :meth:`~robocli.devices.pioneer.Pioneer.request_config` (the caller reads the reply),
    after ``warmup`` unrecorded ones."""
    for _ in range(warmup):
        robot.request_config(timeout=2.0)
    clock = time.perf_counter
    samples = run.samples
    while run.count < run.n:
        start = clock()
        robot.request_config(timeout=2.0)
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


# ---------------------------------------------------------------------------- reporting


def report(
    name: str,
    samples: npt.ArrayLike,
    floor: Stats | None = None,
    targets: tuple[float, float] | None = None,
    where: str = "",
) -> dict[str, Any]:
    """JSON-ready summary of one measurement, in microseconds, with floor multiples.

    ``targets``: (median, p99) limits as multiples of the floor's median; the summary then
    says whether each is met.
    """
    stats = Stats.of(samples)
    out: dict[str, Any] = {"name": name, "unit": "us", **stats.as_dict(1e6)}
    if where:
        out["where"] = where
    if floor is not None and floor.median > 0:
        out["x_floor_median"] = stats.median / floor.median
        out["x_floor_p99"] = stats.p99 / floor.median
        if targets is not None:
            out["target_median_x"], out["target_p99_x"] = targets
            out["target_met"] = bool(
                out["x_floor_median"] <= targets[0] and out["x_floor_p99"] <= targets[1]
            )
    return out
