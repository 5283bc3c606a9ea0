"""The lab bench: the same lab of robots and laptops (:class:`~.netns.Lab`) run over a hub
front-end, and what it costs and delivers.

Each robot namespace runs ``robocli serve --sim`` bound to its own address; each laptop
namespace runs one laptop process (:mod:`.laptop`: a client thread per robot) subscribed to
the IMU and ADC of every robot and to the camera of robot ``laptop % robots``. After a
warm-up the bench counts for ``seconds``: bytes on each robot's uplink (its ``eth0`` counters)
and packets its token bucket dropped, the CPU of each hub (``/proc/PID/stat``), and what each
laptop received (:class:`LabRun`).

Each counter is read at both ends of the window, each read between two clock reads
(:class:`Window`): its rate is its increase over the time between its own two reads. The
counters of a namespace are read through ``ip``/``tc`` processes, which a loaded machine
starts slowly; divided by a clock started after the first reads and stopped before the last
ones, the uplink read 7-9 % over its token bucket's rate.
"""

from __future__ import annotations

import contextlib
import functools
import json
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from robocli.bench.hub import cpu_seconds
from robocli.bench.lab.netns import Lab, LabError, Proc, wait_for

HUB_PORT = 1500
ROUTER_PORT = 7447
ZENOH_PUBLISH = "imu=200,adc=1000"  #: the camera starts when a laptop asks (its settings)
HUB_READY = {"tcp": "hub serving", "zenoh": "hub serving"}
START_S = 60.0  #: bounds the start of hubs and laptops (a loaded machine is slow)
RATES = {"imu": 200.0, "adc": 1000.0, "camera": 15.0}
#: the issue's targets
TARGET_UPLINK_RATIO = 1.2
TARGET_P99_S = 0.050
TARGET_HUB_CORES = 0.3


@dataclass(frozen=True)
class Stamped:
    """One read of a counter: its value and the monotonic times just before and after."""

    value: float
    before: float
    after: float

    @property
    def t(self) -> float:
        """When the value was read, as well as the clock can say: the middle of the read."""
        return (self.before + self.after) / 2


class Window:
    """Counters read at both ends of a counting window (:meth:`start`, :meth:`end`), each
    read bracketed by reads of ``clock``, in the same order at both ends. A counter's
    :meth:`rate` is its increase over the time between its own two reads, so the time the
    other reads take (a process each, on a loaded machine) counts on neither side."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._sources: dict[str, Callable[[], float]] = {}
        self._ends: dict[str, list[Stamped]] = {}

    def add(self, name: str, read: Callable[[], float]) -> None:
        self._sources[name] = read

    def _read_all(self) -> None:
        clock = self._clock
        for name, read in self._sources.items():
            before = clock()
            value = read()
            self._ends.setdefault(name, []).append(Stamped(value, before, clock()))

    def start(self) -> None:
        self._ends.clear()
        self._read_all()

    def end(self) -> None:
        self._read_all()

    def _pair(self, name: str) -> tuple[Stamped, Stamped]:
        ends = self._ends.get(name, [])
        if len(ends) != 2:
            raise LabError(f"counter {name!r} was read {len(ends)} time(s), not at both ends")
        return ends[0], ends[1]

    def delta(self, name: str) -> float:
        first, last = self._pair(name)
        return last.value - first.value

    def seconds(self, name: str) -> float:
        """The time between the two reads of ``name``."""
        first, last = self._pair(name)
        return last.t - first.t

    def rate(self, name: str) -> float:
        """The increase of ``name`` per second between its two reads."""
        span = self.seconds(name)
        if not span > 0:
            raise LabError(f"counter {name!r}: its two reads are {span:g} s apart")
        return self.delta(name) / span

    def error(self) -> float:
        """The largest relative error a rate may have: half of each read's duration, both
        ends, over the time between the reads (where in its bracket a value was taken is
        not known)."""
        return max((sum(e.after - e.before for e in self._pair(n)) / 2 / self.seconds(n)
                    for n in self._sources), default=0.0)  # fmt: skip


@dataclass
class LabRun:
    """One lab run's figures (``sensors``: per sensor, summed or worst over laptops)."""

    mode: str
    robots: int
    laptops: int
    seconds: float
    uplink_mbit: float | None
    camera: str = "spread"
    uplink_bytes: list[int] = field(default_factory=list)  #: per robot, while counting
    uplink_seconds: list[float] = field(default_factory=list)  #: between its counter's reads
    counter_error: float = 0.0  #: the largest relative error of a rate (:meth:`Window.error`)
    uplink_drops: list[int] = field(default_factory=list)  #: tbf drops per robot
    hub_cores: list[float] = field(default_factory=list)  #: per hub, while counting
    laptop_cores: list[float] = field(default_factory=list)  #: per laptop process
    router_cores: float = 0.0  #: the Zenoh router's (0 over ros4mat TCP: no router)
    bridge_cores: list[float] = field(default_factory=list)  #: per Pioneer bridge (--bridge)
    sensors: dict[str, dict[str, Any]] = field(default_factory=dict)
    errors: list[str] = field(default_factory=list)
    laptop_seconds: float = 0.0  #: the laptops' counting windows, summed

    @property
    def uplink_bytes_s(self) -> float:
        """Bytes per second on the busiest robot uplink (each over its own counter's window)."""
        spans = self.uplink_seconds or [self.seconds] * len(self.uplink_bytes)
        return max((b / s for b, s in zip(self.uplink_bytes, spans, strict=True)), default=0.0)

    @property
    def uplink_mbit_s(self) -> float:
        """Mean bit rate of the busiest robot uplink, Mbit/s."""
        return self.uplink_bytes_s * 8 / 1e6

    def expected(self, sensor: str) -> float:
        """Samples of ``sensor`` the laptops would receive in their counting windows at the
        nominal rate."""
        per = self.robots if sensor != "camera" else 1
        return RATES[sensor] * (self.laptop_seconds or self.seconds * self.laptops) * per

    def as_dict(self) -> dict[str, Any]:
        d = dict(self.__dict__)
        d["uplink_mbit_s"] = self.uplink_mbit_s
        return d


def _hub_argv(mode: str, address: str, name: str, config: Path) -> list[str]:
    if mode == "tcp":
        return [sys.executable, "-m", "robocli", "serve", "--sim", "--bind", address, "--port",
                str(HUB_PORT), "--max-clients", "4096"]  # fmt: skip
    if mode == "zenoh":  # a client of the router (its config file), on Zenoh only
        return [sys.executable, "-m", "robocli", "serve", "--sim", "--zenoh", str(config),
                "--name", name, "--publish", ZENOH_PUBLISH, "--no-tcp"]  # fmt: skip
    raise LabError(f"unknown front-end {mode!r}")


#: Zenoh's shared-memory transport off: the lab's namespaces share the host's /dev/shm, and
#: with it on, every message over 3 KB (each camera frame) went from hub to laptop through
#: shared memory, never on the robot's uplink (the uplink counted 0.3 of the bytes the
#: laptop received). Robots on Wi-Fi share no memory with laptops.
NO_SHM = {"shared_memory": {"enabled": False}}


def client_config(path: Path, router: str) -> Path:
    """A Zenoh configuration file: a client of ``router`` listening nowhere (a hub and a
    bridge share a robot's namespace), multicast scouting off, no shared memory
    (:data:`NO_SHM`)."""
    config = {"mode": "client", "connect": {"endpoints": [router]}, "listen": {"endpoints": []},
              "scouting": {"multicast": {"enabled": False}}, "transport": NO_SHM}  # fmt: skip
    path.write_text(json.dumps(config, indent=1))
    return path


def start_router(lab: Lab) -> tuple[Proc, str]:
    """``robocli router`` listening on the server namespace's address (no shared memory)."""
    assert lab.logdir is not None
    endpoint = f"tcp/{lab.server.address}:{ROUTER_PORT}"
    config = lab.logdir / "router.json5"
    config.write_text(json.dumps({"scouting": {"multicast": {"enabled": False}},
                                  "transport": NO_SHM}))  # fmt: skip
    argv = [sys.executable, "-m", "robocli", "router", "--config", str(config), "--zenoh",
            endpoint]  # fmt: skip
    proc = lab.spawn(lab.server, argv, "router")
    wait_for(lambda: "router" in proc.tail().lower() and endpoint in proc.tail(), START_S,
             "the router", [proc])  # fmt: skip
    return proc, endpoint


def _merge(into: dict[str, dict[str, Any]], laptop: dict[str, Any]) -> None:
    """Sum counts over laptops; keep the worst p99/max and the median of p50s (as a list)."""
    for sensor, r in laptop["sensors"].items():
        m = into.setdefault(sensor, {"samples": 0, "lost": 0, "duplicates": 0, "bytes": 0,
                                     "p50s": [], "p99": None, "max": None})  # fmt: skip
        for k in ("samples", "lost", "duplicates", "bytes"):
            m[k] += r[k]
        if r["p50"] is not None:
            m["p50s"].append(r["p50"])
        for k in ("p99", "max"):
            if r[k] is not None:
                m[k] = r[k] if m[k] is None else max(m[k], r[k])


def run_lab(
    mode: str,
    robots: int,
    laptops: int,
    *,
    seconds: float = 10.0,
    warmup: float = 2.0,
    uplink_mbit: float | None = 20.0,
    poll: int = 25,
    camera: str = "spread",
    bridge: bool = False,
) -> LabRun:
    """Build a lab, run it over front-end ``mode`` ("tcp": ros4mat), count for ``seconds``
    after ``warmup``, tear it all down; the figures. ``camera``: "spread" (laptop *j*
    watches robot *j % robots*) or "one" (the whole class watches robot 0)."""
    if camera not in ("spread", "one"):
        raise LabError(f"camera: 'spread' or 'one', not {camera!r}")
    result = LabRun(mode, robots, laptops, seconds, uplink_mbit, camera)
    with Lab(robots, laptops, uplink_mbit=uplink_mbit) as lab:
        assert lab.logdir is not None
        hubs: list[Proc] = []
        router = ""
        router_proc: Proc | None = None
        if mode == "zenoh":
            router_proc, router = start_router(lab)
        config = client_config(lab.logdir / "client.json5", router)
        for i in range(robots):
            node = lab.robot(i)
            argv = _hub_argv(mode, node.address, f"r{i}", config)
            hubs.append(lab.spawn(node, argv, f"hub{i}"))
        bridges = _start_bridges(lab, mode, config) if bridge else []
        for h in hubs:
            wait_for(lambda h=h: HUB_READY[mode] in h.tail(), START_S, f"{h.name} start", [h])
        if mode == "tcp":
            addresses = ",".join(f"{lab.robot(i).address}:{HUB_PORT}" for i in range(robots))
        else:
            addresses = ",".join(f"r{i}" for i in range(robots))
        tops: list[tuple[Proc, str]] = []
        for j in range(laptops):
            out = str(lab.logdir / f"laptop{j}.json")
            watched = j % robots if camera == "spread" else 0
            argv = [sys.executable, "-m", "robocli.bench.lab.laptop", "--mode", mode,
                    "--hubs", addresses, "--camera", str(watched), "--poll", str(poll),
                    "--out", out, "--router", str(config)]  # fmt: skip
            tops.append((lab.spawn(lab.laptop(j), argv, f"laptop{j}", stdin=True), out))
        for p, _ in tops:
            wait_for(lambda p=p: "ready" in p.tail(), START_S, f"{p.name} ready", [p])
        time.sleep(warmup)  # the rings and queues settle before counting
        window = _window(lab, hubs, [p for p, _ in tops], router_proc, bridges)
        window.start()
        for p, _ in tops:
            _say(p, "go")
        t0 = time.monotonic()
        time.sleep(seconds)
        result.seconds = time.monotonic() - t0
        window.end()
        rng = range(robots)
        result.uplink_bytes = [int(window.delta(f"tx{i}")) for i in rng]
        result.uplink_seconds = [window.seconds(f"tx{i}") for i in rng]
        result.uplink_drops = [int(window.delta(f"drops{i}")) for i in rng]
        result.hub_cores = [window.rate(f"hub{i}") for i in range(len(hubs))]
        result.laptop_cores = [window.rate(f"laptop{j}") for j in range(len(tops))]
        if router_proc is not None:
            result.router_cores = window.rate("router")
        result.bridge_cores = [window.rate(f"bridge{i}") for i in range(len(bridges))]
        result.counter_error = window.error()
        for p, _ in tops:
            _say(p, "stop")
        for p, out in tops:
            wait_for(lambda p=p: p.popen.poll() is not None, START_S, f"{p.name} report")
            try:
                with open(out) as f:
                    report = json.load(f)
            except (OSError, ValueError) as exc:
                raise LabError(f"{p.name} wrote no report ({exc}):\n{p.tail()}") from None
            _merge(result.sensors, report)
            result.laptop_seconds += float(report["seconds"])
            result.errors += [f"{p.name}: {e}" for e in report["errors"]]
    return result


def _window(lab: Lab, hubs: list[Proc], laptops: list[Proc], router: Proc | None,
            bridges: list[Proc]) -> Window:  # fmt: skip
    """The run's counters: each robot's uplink bytes and token-bucket drops, the CPU seconds
    of each hub, laptop, the router and each bridge."""
    window = Window()
    for i in range(lab.robots):
        node = lab.robot(i)
        window.add(f"tx{i}", functools.partial(lab.tx_bytes, node))
        window.add(f"drops{i}", functools.partial(lab.qdisc_drops, node))
    named = [(f"hub{i}", h) for i, h in enumerate(hubs)]
    named += [(f"laptop{j}", p) for j, p in enumerate(laptops)]
    named += [("router", router)] if router is not None else []
    named += [(f"bridge{i}", b) for i, b in enumerate(bridges)]
    for name, proc in named:
        window.add(name, functools.partial(cpu_seconds, proc.pid))
    return window


def _start_bridges(lab: Lab, mode: str, config: Path) -> list[Proc]:
    """A simulated Pioneer and its Zenoh bridge (``p<i>``) in each robot's namespace: a
    client of the router over Zenoh, else listening on the robot's address."""
    py = sys.executable
    bridges = []
    for i in range(lab.robots):
        node = lab.robot(i)
        sim = lab.spawn(node, [py, "-m", "robocli", "sim", "pioneer", "--port", "8101"],
                        f"pioneer{i}")  # fmt: skip
        wait_for(lambda sim=sim: "tcp://" in sim.tail(), START_S, sim.name, [sim])
        where = str(config) if mode == "zenoh" else f"tcp/{node.address}:{ROUTER_PORT}"
        bridges.append(lab.spawn(node, [py, "-m", "robocli", "bridge", "pioneer",
                                        "tcp://127.0.0.1:8101", "--zenoh", where, "--name",
                                        f"p{i}"], f"bridge{i}"))  # fmt: skip
    for b in bridges:
        wait_for(lambda b=b: "bridge p" in b.tail(), START_S, b.name, [b])
    return bridges


def _say(proc: Proc, line: str) -> None:
    assert proc.popen.stdin is not None
    with contextlib.suppress(OSError):
        proc.popen.stdin.write(line + "\n")
        proc.popen.stdin.flush()
