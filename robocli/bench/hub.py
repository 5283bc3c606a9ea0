"""Benchmarks of the sensor hub through the real client: empty-pull round trips and the
many-client throughput target.

The hub runs in its own process (:func:`hub_process`) so that its CPU time and peak memory
are its own (``/proc/PID/stat`` and ``VmHWM``); clients run in worker processes, each with
a thread per client, :data:`CLIENTS_PER_WORKER` to a process by default. A lab's ros4mat
clients are separate MATLAB processes; packing 20 clients into one interpreter measured that
interpreter's queue for its GIL, not the hub: at the full target p99 pull was 14-19 ms with
2 workers and 2.0-3.2 ms with 4 to 20 (README).

Throughput target (issue 9): 40 clients, each subscribed to IMU 200 Hz, ADC 1 kHz, a
1081-beam laser at 40 Hz and a 320x240 camera at 30 Hz, each pulling every sensor at 20 Hz:
no sample lost within buffer capacity, p99 pull <= 5 ms, the hub <= 1 core.
"""

from __future__ import annotations

import contextlib
import json
import os
import random
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from robocli.bench.harness import child_process, read_line
from robocli.bench.stats import Run
from robocli.errors import RobocliError, TransportError

#: Sensor (as the bench names it) -> (ros4mat name, subscribe arguments).
BENCH_SENSORS: dict[str, tuple[str, dict[str, Any]]] = {
    "imu": ("imu", {"rate": 200}),
    "adc": ("adc", {"rate": 1000}),
    "laser": ("hokuyo", {"rate": 40}),
    "camera": ("camera", {"rate": 30, "resolution": "320x240"}),
    "gps": ("gps", {"rate": 5}),
    "battery": ("battery", {"rate": 10}),
    "sysinfo": ("computer", {"rate": 10}),
}
TARGET_P99_S = 5e-3
FIRST_SAMPLE_S = 10.0  #: a client waits this long for each sensor's first sample
CLIENTS_PER_WORKER = 5  #: default client threads per worker process
TARGET_CORES = 1.0


@dataclass
class HubProcess:
    """A simulated hub running in a child process (see :func:`hub_process`)."""

    url: str
    pid: int
    proc: subprocess.Popen[str]

    @property
    def address(self) -> str:
        return self.url.removeprefix("tcp://")

    def stats(self, timeout: float = 5.0) -> dict[str, Any] | None:
        """The hub's counters (None when it does not answer): ``dropped_seen``, the samples
        it dropped for its clients so far because their buffers overflowed, before samples
        they pulled (what their gaps show: a cursor that overflowed after its client's last
        pull is not counted; clients that sent QUIT are forgotten); ``pull``, percentiles
        (s) of its own time per pull, request framed to reply built (its last 65,536)."""
        assert self.proc.stdin is not None
        try:
            self.proc.stdin.write("stats\n")
            self.proc.stdin.flush()
        except OSError:
            return None
        line = read_line(self.proc, timeout)
        return dict(json.loads(line)) if line.startswith("{") else None

    def dropped(self, timeout: float = 5.0) -> int | None:
        """``dropped_seen`` of :meth:`stats`."""
        stats = self.stats(timeout)
        return None if stats is None else int(stats["dropped_seen"])


@contextlib.contextmanager
def hub_process(timeout: float = 20.0) -> Iterator[HubProcess]:
    """A simulated hub in a child process (:func:`~robocli.bench.harness.child_process`: it
    stops at the end of its stdin)."""
    code = "from robocli.bench.hub import _hub_child; _hub_child()"
    with child_process(code, timeout=timeout) as (proc, line):
        if not line.startswith("tcp://"):
            raise TransportError(f"the hub process did not start within {timeout:g} s {line}")
        yield HubProcess(line, proc.pid, proc)


def _hub_child() -> None:
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent stops us
    from robocli.hub_server import HubServer
    from robocli.hub_server.server import tune_hub_process

    tune_hub_process()  # measure the hub as `robocli serve` runs it
    with HubServer(bind="127.0.0.1", port=0, sim=True) as srv:
        print(srv.url, flush=True)
        for line in sys.stdin:  # until the parent closes the pipe (or dies)
            if line.strip() == "stats":
                print(json.dumps({"dropped": sum(c.dropped for c in srv.clients),
                                  "dropped_seen": srv.hub.dropped_seen(),
                                  "pull": srv.pull_times.percentiles()}), flush=True)  # fmt: skip


def cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of a process so far (Linux ``/proc``)."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def peak_rss(pid: int) -> int:
    """Peak resident memory of a process in bytes (``VmHWM``)."""
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024
    return 0


def rtt(address: str, run: Run, warmup: int = 20) -> Run:
    """Round trips of empty pulls (a GPS subscribed at 1 Hz: nearly every pull is empty)."""
    from robocli.devices.hub.client import Hub

    with Hub.connect(address) as hub:
        hub.subscribe("gps", 1)
        for _ in range(warmup):
            hub.pull("gps")
        clock = time.perf_counter
        while run.count < run.n:
            t0 = clock()
            hub.pull("gps")
            run.samples[run.count] = clock() - t0
            run.count += 1
    return run


#: what a client counts of each sensor, summed over the clients into the results
_COUNTS = ("pulls", "samples", "bytes", "lost")


def _client(
    address: str, sensors: list[str], pull_hz: float, start: float, end: float,
    out: dict[str, Any], lock: threading.Lock, quit_at_end: bool,
) -> None:  # fmt: skip
    """One client: subscribes, then pulls every sensor at ``pull_hz`` until ``end``; pulls,
    samples, bytes and latency are counted from ``start`` (while all the clients pull), the
    gaps in the sample times (``lost``) from its first pull on, as the hub counts what it
    dropped for it (:meth:`HubProcess.dropped`)."""
    from robocli.devices.hub.client import Hub

    lat: list[float] = []
    tally = {s: dict.fromkeys(_COUNTS, 0) for s in sensors}
    try:
        hub = Hub.connect(address, timeout=10.0)
        try:
            for s in sensors:
                name, args = BENCH_SENSORS[s]
                hub.subscribe(name, **args)
            period = 1.0 / pull_hz
            # the first samples of each sensor, pulled as soon as they come: the gaps are
            # counted from them (the Hub's own count, Reading.lost), before any buffer can
            # overflow; then the pulls, spread over a period
            for s in sensors:
                name = BENCH_SENSORS[s][0]
                deadline = time.monotonic() + FIRST_SAMPLE_S
                while not len(r := hub.read(name)) and time.monotonic() < deadline:
                    time.sleep(0.002)
                tally[s]["lost"] += r.lost
            due = time.time() + random.random() * period
            while due < end:
                time.sleep(max(0.0, due - time.time()))
                counted = due >= start
                for s in sensors:
                    name, args = BENCH_SENSORS[s]
                    t0 = time.perf_counter()
                    r = hub.read(name)
                    tk = tally[s]
                    tk["lost"] += r.lost
                    if counted:
                        lat.append(time.perf_counter() - t0)
                        tk["pulls"] += 1
                        tk["samples"] += len(r)
                        tk["bytes"] += r.nbytes
                due += period
        finally:  # our own hub keeps detached clients: it can tell what it dropped for them
            hub.close(stop=quit_at_end)
    except RobocliError as exc:
        with lock:
            out.setdefault("errors", []).append(str(exc))
    with lock:
        out["latency"].extend(lat)
        for s, tk in tally.items():
            agg = out["sensors"].setdefault(s, dict.fromkeys(_COUNTS, 0))
            for key, n in tk.items():
                agg[key] += n


def _worker_main() -> None:
    """A worker process: argv[1] is a JSON job; prints its results as one JSON line.
    Ctrl-C reaches the whole process group: the worker ignores it, the parent stops it."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    job = json.loads(sys.argv[1])
    out: dict[str, Any] = {"latency": [], "sensors": {}}
    lock = threading.Lock()
    keys = ("address", "sensors", "pull_hz", "start", "end")
    args = (*(job[k] for k in keys), out, lock, job["quit"])
    threads = [
        threading.Thread(target=_client, args=args, daemon=True) for _ in range(job["clients"])
    ]
    for th in threads:
        th.start()
    for th in threads:
        th.join(max(1.0, job["end"] - time.time() + 15))
    print(json.dumps(out), flush=True)


def throughput(
    address: str,
    *,
    clients: int = 40,
    sensors: tuple[str, ...] = ("imu", "adc", "laser", "camera"),
    seconds: float = 10.0,
    pull_hz: float = 20.0,
    workers: int | None = None,
    hub: HubProcess | None = None,
    served: tuple[str, ...] | None = None,
) -> dict[str, Any]:
    """Run ``clients`` clients (in ``workers`` processes; default: one per
    :data:`CLIENTS_PER_WORKER` clients) pulling ``sensors`` at ``pull_hz`` for ``seconds``;
    with ``hub`` (ours, in its own process), the hub's CPU (cores), peak memory and the
    samples it dropped for overflowing buffers too. Sensors the hub does not serve
    (``served``: the ros4mat names it serves) are left out and listed."""
    unknown = [s for s in sensors if s not in BENCH_SENSORS]
    if unknown:
        raise RobocliError(f"bench: unknown sensor {unknown[0]!r}; from {sorted(BENCH_SENSORS)}")
    used = [s for s in sensors if served is None or BENCH_SENSORS[s][0] in served]
    skipped = [s for s in sensors if s not in used]
    if workers is None:
        workers = -(-clients // CLIENTS_PER_WORKER)
    workers = max(1, min(workers, clients))
    start = time.time() + 1.5 + 0.05 * clients
    end = start + seconds
    procs: list[subprocess.Popen[str]] = []
    dropped0 = hub.dropped() if hub is not None else None  # a hub may serve several runs
    before = _children_cpu()
    spawned = time.time()
    try:
        for w in range(workers):
            n = clients // workers + (1 if w < clients % workers else 0)
            job = {"address": address, "sensors": used, "pull_hz": pull_hz, "start": start,
                   "end": end, "clients": n, "quit": hub is None}  # fmt: skip
            code = "from robocli.bench.hub import _worker_main; _worker_main()"
            procs.append(subprocess.Popen(
                [sys.executable, "-c", code, json.dumps(job)], stdout=subprocess.PIPE, text=True,
            ))  # fmt: skip
        cpu0 = rss = 0.0
        if hub is not None:
            time.sleep(max(0.0, start - time.time()))
            cpu0 = cpu_seconds(hub.pid)
            time.sleep(max(0.0, end - time.time()))
            cpu1 = cpu_seconds(hub.pid)
            rss = peak_rss(hub.pid)
        results = []
        for proc in procs:
            out, _ = proc.communicate(timeout=seconds + 60)
            results.append(json.loads(out.strip().splitlines()[-1]))
        # after the clients' last pulls: what the hub dropped before samples they pulled
        end_stats = hub.stats() if hub is not None else None
        dropped1 = None if end_stats is None else int(end_stats["dropped_seen"])
    finally:  # interrupted (or failed): no worker outlives the bench
        _stop_workers(procs)
    client_cores = (_children_cpu() - before) / max(time.time() - spawned, 1e-9)
    lat = np.concatenate([np.asarray(r["latency"], dtype=np.float64) for r in results])
    per: dict[str, dict[str, int]] = {}
    for r in results:
        for s, agg in r["sensors"].items():
            dst = per.setdefault(s, dict.fromkeys(agg, 0))
            for k, v in agg.items():
                dst[k] += v
    total = {k: sum(p[k] for p in per.values()) for k in ("pulls", "samples", "bytes", "lost")}
    report: dict[str, Any] = {
        "clients": clients, "sensors": used, "not_served": skipped, "seconds": seconds,
        "pull_hz": pull_hz, "workers": workers, "pulls_per_s": total["pulls"] / seconds,
        "samples_per_s": total["samples"] / seconds, "bytes_per_s": total["bytes"] / seconds,
        "lost_samples": total["lost"], "per_sensor": per,
        "client_cpu_cores": client_cores,
        "errors": [e for r in results for e in r.get("errors", [])],
    }  # fmt: skip
    if lat.size:
        p50, p99 = np.percentile(lat, [50, 99])
        report.update(pull_p50_ms=p50 * 1e3, pull_p99_ms=p99 * 1e3, pull_max_ms=lat.max() * 1e3)
    if hub is not None:
        report["hub_cpu_cores"] = (cpu1 - cpu0) / seconds
        report["hub_peak_rss_mb"] = rss / 2**20
        if dropped0 is not None and dropped1 is not None:
            report["hub_dropped"] = dropped1 - dropped0
        if end_stats is not None:  # the hub's own part of a pull, whole session
            report["hub_pull_p50_ms"] = end_stats["pull"]["p50"] * 1e3
            report["hub_pull_p99_ms"] = end_stats["pull"]["p99"] * 1e3
    report["targets_met"] = bool(
        not report["errors"] and total["lost"] == 0 and not report.get("hub_dropped")
        and report.get("pull_p99_ms", 1e9) <= TARGET_P99_S * 1e3
        and report.get("hub_cpu_cores", 0.0) <= TARGET_CORES
    )  # fmt: skip
    return report


def _stop_workers(procs: list[subprocess.Popen[str]]) -> None:
    """Terminate the workers still running (they ignore SIGINT), then reap them, bounded."""
    for proc in procs:
        if proc.poll() is None:
            proc.terminate()
    for proc in procs:
        try:
            proc.wait(2.0)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(2.0)
        if proc.stdout is not None:
            proc.stdout.close()


def _children_cpu() -> float:
    import resource

    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def served_sensors(address: str) -> tuple[str, ...]:
    """The ros4mat names of the sensors a hub accepts a subscription to (probed)."""
    from robocli.devices.hub.client import Hub
    from robocli.errors import DeviceError

    names = []
    with Hub.connect(address) as hub:
        for name, args in BENCH_SENSORS.values():
            try:
                hub.subscribe(name, **args)
            except DeviceError:
                continue
            names.append(name)
    return tuple(names)


__all__ = [
    "BENCH_SENSORS",
    "CLIENTS_PER_WORKER",
    "HubProcess",
    "cpu_seconds",
    "hub_process",
    "peak_rss",
    "rtt",
    "served_sensors",
    "throughput",
]
