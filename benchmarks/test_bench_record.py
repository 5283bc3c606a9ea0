"""What recording a Pioneer costs the client, per SIP (target: <= 10 us of client CPU).

Three figures, each over recorded SIPs of a real session (``tests/data/arcos``):

- the listener, in the thread that read the SIP (the one that keeps the robot safe): a
  queue append under a short lock;
- the writer thread's work for one SIP: the raw frame, decoding, the pose, transform,
  sonar-scan and state messages as JSON, the MCAP records and (amortised) zstd;
- a whole session against the simulator in this process, 100 SIPs/s, with and without a
  recorder: the process CPU time per SIP, the difference being what recording adds.

Run with ``make bench`` (or ``pytest benchmarks/test_bench_record.py``).
"""

from __future__ import annotations

import io
import threading
import time
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("mcap")

from robocli.io.capture import read_capture
from robocli.io.record import Recorder
from robocli.io.record.pioneer import PioneerDecoder
from robocli.robots.pioneer import ROBOT_PARAMS

TRACE = Path(__file__).resolve().parents[1] / "tests/data/arcos/b_simpleMotionCommands.jsonl"
N = 20_000


@pytest.fixture(scope="module")
def sips() -> list[bytes]:
    """SIP payloads as the Pioneer's listeners see them (type byte + body)."""
    found = [f.frame[3:-2] for f in read_capture(TRACE)
             if f.direction == "rx" and f.frame[3] & 0xF0 == 0x30]  # fmt: skip
    return (found * (N // len(found) + 1))[:N]


def test_listener_per_sip(benchmark: Any, sips: list[bytes]) -> None:
    """The device thread's share: one queue append per SIP (the writer drains meanwhile)."""
    rec = Recorder(io.BytesIO(), max_queue=10 * N, max_queue_bytes=1 << 30)
    link = rec.listener("pioneer", "arcos")
    try:

        def feed() -> float:
            start = time.thread_time()
            for i, payload in enumerate(sips):
                link("rx", payload, i * 0.1)
            return (time.thread_time() - start) / len(sips)

        per_sip = benchmark.pedantic(feed, rounds=3, iterations=1)
        benchmark.extra_info["listener_us_per_sip"] = per_sip * 1e6
        print(f"\nlistener: {per_sip * 1e6:.2f} us per SIP (last round)")
        assert rec.stats.dropped == 0
    finally:
        rec.close()


def _writer_per_sip(sips: list[bytes], baseline: bool) -> float:
    """Thread CPU seconds the writer spends per SIP (run here in the calling thread, the
    writer thread idle); ``baseline``: as it was before, each message through the mcap
    package's own ``add_message``, the state message built as a dict and encoded by
    ``json``."""
    rec = Recorder(io.BytesIO(), chunk_seconds=3600)
    link = rec.listener("pioneer", "arcos")
    decoder = PioneerDecoder(rec, "pioneer", ROBOT_PARAMS["p3dx"])
    link.decoder = decoder
    if baseline:
        rec._add_message = rec._writer.add_message  # type: ignore[method-assign]
        decoder._state = decoder._state_dict  # type: ignore[method-assign]
    handle = link._handle
    try:
        start = time.thread_time()
        for i, payload in enumerate(sips):
            handle("rx", payload, i * 0.1)
        return (time.thread_time() - start) / len(sips)
    finally:
        rec.close()


def test_writer_per_sip(benchmark: Any, sips: list[bytes]) -> None:
    """The writer thread's share: raw + pose + transform + sonar scan + state, encoded and
    added to zstd chunks, now and as before (in the same run, alternating: the ratio is
    the figure; a loaded machine moves both)."""
    runs: list[tuple[float, float]] = []

    def both() -> None:
        runs.append((_writer_per_sip(sips, True), _writer_per_sip(sips, False)))

    benchmark.pedantic(both, rounds=3, iterations=1)
    before = min(b for b, _ in runs)
    now = min(n for _, n in runs)
    ratios = sorted(n / b for b, n in runs)
    benchmark.extra_info.update({"writer_us_per_sip": now * 1e6,
                                 "writer_us_per_sip_before": before * 1e6,
                                 "writer_ratio_median": ratios[len(ratios) // 2]})  # fmt: skip
    each = ", ".join(f"{r:.2f}" for r in ratios)
    print(f"\nwriter: {now * 1e6:.1f} us per SIP, before {before * 1e6:.1f} us (best of "
          f"{len(runs)}); now/before per round: {each}")  # fmt: skip


def _thread_cpu(name: str) -> float:
    """CPU seconds of the live thread called ``name`` (Linux per-thread clocks)."""
    thread = next(t for t in threading.enumerate() if t.name == name)
    assert thread.ident is not None
    return time.clock_gettime(time.pthread_getcpuclockid(thread.ident))


def _session(record: bool, n: int = 300) -> dict[str, float]:
    """A session against the simulator (100 SIPs/s, in this process): CPU seconds per SIP
    of the client's reader thread, of the recorder's writer thread, and of the process."""
    from robocli.devices.pioneer import Pioneer
    from robocli.sim.pioneer.server import PioneerSim

    with PioneerSim("p3dx", sip_ms=10.0) as sim:
        url = sim.serve_tcp("127.0.0.1", 0)
        rec = Recorder(io.BytesIO()) if record else None
        try:
            with Pioneer.connect(url) as robot:
                if rec is not None:
                    rec.add(robot)
                robot.wait_for_sip()
                first = robot.stats.sips
                reader0, process0 = _thread_cpu("pioneer-reader"), time.process_time()
                writer0 = _thread_cpu("recorder") if rec is not None else 0.0
                while robot.stats.sips < first + n:
                    robot.wait_for_sip()
                sips = robot.stats.sips - first
                reader = _thread_cpu("pioneer-reader") - reader0
                if rec is not None:  # the writer's backlog belongs to these SIPs
                    while rec.stats.messages < 5 * (sips + 1):
                        time.sleep(0.01)
                writer = _thread_cpu("recorder") - writer0 if rec is not None else 0.0
                process = time.process_time() - process0
                return {"reader": reader / sips, "writer": writer / sips,
                        "process": process / sips}  # fmt: skip
        finally:
            if rec is not None:
                rec.close()


def test_session_cpu_per_sip(benchmark: Any) -> None:
    """A live session with and without recording: what the reader thread (the robot's),
    the writer thread and the whole process spend per SIP."""

    def both() -> tuple[dict[str, float], dict[str, float]]:
        return _session(False), _session(True)

    without, with_rec = benchmark.pedantic(both, rounds=2, iterations=1)
    info = {
        "reader_us_per_sip_without": without["reader"] * 1e6,
        "reader_us_per_sip_recording": with_rec["reader"] * 1e6,
        "writer_us_per_sip": with_rec["writer"] * 1e6,
        "process_us_per_sip_without": without["process"] * 1e6,
        "process_us_per_sip_recording": with_rec["process"] * 1e6,
    }
    benchmark.extra_info.update(info)
    print("\n" + "\n".join(f"{k}: {v:.1f}" for k, v in info.items()))


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_camera_write_throughput(benchmark: Any, compression: str) -> None:
    """Camera replies (320x240 raw RGB, from the simulated hub) through the writer's whole
    path: the raw channel, the RawImage JSON with its base64 pixels, MCAP, compression.
    Reported in MB/s of camera replies (target >= 100 MB/s)."""
    from robocli.devices.hub.client import Hub
    from robocli.hub_server import HubServer
    from robocli.io.record.links import RawLink

    replies: list[bytes] = []
    with HubServer(port=0, sim=True) as srv, Hub.connect(f"127.0.0.1:{srv.port}") as hub:
        hub.subscribe("camera", rate=30, resolution="320x240")
        hub.session.listeners.add(
            lambda d, f, t: replies.append(f) if d == "rx" and f[0] == 0x24 and len(f) > 1000
            else None)  # fmt: skip
        deadline = time.monotonic() + 30
        while len(replies) < 5 and time.monotonic() < deadline:
            hub.read("camera")
            time.sleep(0.05)
        assert len(replies) >= 5
        rec = Recorder(io.BytesIO(), compression=compression, chunk_seconds=3600)
        try:
            rec.add(hub)
            link = next(x for x in hub.session.listeners._items
                        if isinstance(x, RawLink))  # fmt: skip
            handle = link._handle

            def write() -> float:
                start, size = time.perf_counter(), 0
                for k in range(40):
                    handle("rx", replies[k % 5], time.monotonic())
                    size += len(replies[k % 5])
                return size / (time.perf_counter() - start)

            rate = benchmark.pedantic(write, rounds=3, iterations=1)
        finally:
            rec.close()
    benchmark.extra_info["camera_mb_per_s"] = rate / 1e6
    print(f"\ncamera replies, {compression}: {rate / 1e6:.0f} MB/s (last round)")
