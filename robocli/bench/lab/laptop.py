"""One laptop of the lab (``python -m robocli.bench.lab.laptop``), run in its namespace.

A laptop is **one process holding one client per robot** (a thread each): 40 interpreters
per robot would not fit in the lab machine's 2 cores, and a student's MATLAB session also
holds its connections in one process. Each client subscribes to the robot's IMU (200 Hz)
and ADC (1 kHz); one robot's client also to its camera (320x240 JPEG, 15 fps).

Talk with the bench (:mod:`.bench`): the laptop prints ``ready`` once every client is
subscribed; it counts from the line ``go`` on its stdin to the line ``stop`` (or the end of
stdin), then writes its tally as JSON to ``--out`` and exits. Counted per sensor: samples
delivered, samples lost (gaps in the acquisition times over 1.5 periods), duplicates (a
time not after the last one), and the latency of each sample (receive time minus the hub's
acquisition time: every namespace shares the host's clock).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import struct
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: sensor -> subscribe arguments (the issue's lab)
SENSORS: dict[str, dict[str, Any]] = {
    "imu": {"rate": 200},
    "adc": {"rate": 1000},
    "camera": {"rate": 15, "resolution": "320x240", "quality": 80},
}
#: the camera's settings as the hub's Zenoh settings queryable takes them (the source's names)
ZENOH_CAMERA = {"fps": 15, "width": 320, "height": 240, "compression": 80}
MAX_LATENCIES = 200_000  #: latencies kept per sensor (a bound; the rest only counted)


@dataclass
class Tally:
    """What one laptop received of one sensor (over every robot) while counting."""

    samples: int = 0
    lost: int = 0
    duplicates: int = 0
    nbytes: int = 0
    latencies: list[np.ndarray[Any, Any]] = field(default_factory=list)
    kept: int = 0

    def add(self, hub_t: np.ndarray[Any, Any], received: float, lost: int, nbytes: int) -> None:
        self.samples += len(hub_t)
        self.lost += lost
        self.nbytes += nbytes
        if self.kept < MAX_LATENCIES and len(hub_t):
            self.latencies.append(received - np.asarray(hub_t, dtype=np.float64))
            self.kept += len(hub_t)

    def report(self) -> dict[str, Any]:
        lat = np.concatenate(self.latencies) if self.latencies else np.zeros(0)
        pct = np.percentile(lat, [50, 99]).tolist() if lat.size else [None, None]
        return {
            "samples": self.samples, "lost": self.lost, "duplicates": self.duplicates,
            "bytes": self.nbytes, "p50": pct[0], "p99": pct[1],
            "max": float(lat.max()) if lat.size else None,
        }  # fmt: skip


class Laptop:
    """The clients of one laptop and their tallies."""

    def __init__(self) -> None:
        self.counting = threading.Event()
        self.stopping = threading.Event()
        self.lock = threading.Lock()
        self.tallies: dict[str, Tally] = {}
        self.errors: list[str] = []
        self.ready = 0

    def tally(self, sensor: str) -> Tally:
        return self.tallies.setdefault(sensor, Tally())

    def record(self, sensor: str, hub_t: Any, last: dict[str, float], lost: int, n: int) -> None:
        received = time.time()
        ts = np.asarray(hub_t, dtype=np.float64)
        prev = last.get(sensor, -np.inf)
        dup = int(np.count_nonzero(np.diff(np.concatenate(([prev], ts))) <= 0)) if len(ts) else 0
        if len(ts):
            last[sensor] = max(prev, float(ts.max()))
        if not self.counting.is_set():
            return
        with self.lock:
            t = self.tally(sensor)
            t.add(ts, received, lost, n)
            t.duplicates += dup

    # ------------------------------------------------------------ ros4mat TCP

    def tcp_client(self, address: str, sensors: list[str], poll: int) -> None:
        from robocli.devices.hub.client import Hub

        try:
            with Hub.connect(address, hub_clock=True, timeout=10.0) as hub:
                for s in sensors:
                    args = dict(SENSORS[s])
                    rate = args.pop("rate")
                    hub.subscribe(s, rate, poll=min(poll, rate), **args)
                with self.lock:
                    self.ready += 1
                last: dict[str, float] = {}
                period = 1.0 / poll
                next_t = time.monotonic()
                while not self.stopping.is_set():
                    for s in sensors:
                        r = hub.read(s)
                        self.record(s, r.hub_t, last, r.lost, r.nbytes)
                    next_t += period
                    delay = next_t - time.monotonic()
                    if delay > 0:
                        self.stopping.wait(delay)
                    else:
                        next_t = time.monotonic()  # late: no burst of catch-up pulls
        except Exception as exc:  # a client's failure is reported, the others go on
            with self.lock:
                self.errors.append(f"{address}: {type(exc).__name__}: {exc}")
                self.ready += 1

    # ------------------------------------------------------------ Zenoh

    def zenoh_clients(self, endpoint: str, hubs: list[str], camera: int) -> list[Any]:
        """One Zenoh session (a client of the router: ``endpoint`` or a config) subscribed to the
        IMU and ADC of every hub and to the camera of hub ``camera``, which it asks to run
        at the lab's settings. Batches are read as a program that is not robocli would:
        the documented 32-byte header (:data:`BATCH`), then ros4mat records whose ``t``
        is the acquisition time; each sample's latency is taken as its batch arrives."""
        from robocli.zenoh.keys import settings_key, topic_key
        from robocli.zenoh.session import open_session

        session = open_session(endpoint, "client")
        subs: list[Any] = [session]
        for i, name in enumerate(hubs):
            for sensor in ["imu", "adc"] + (["camera"] if i == camera else []):
                if sensor == "camera":
                    params = json.dumps({"params": ZENOH_CAMERA})
                    for reply in session.get(settings_key(name, "camera"), payload=params,
                                             timeout=10.0):  # fmt: skip
                        if reply.err is not None:
                            err = reply.err.payload.to_string()
                            self.errors.append(f"{name}: camera settings: {err}")
                handler = _BatchReader(self, sensor)
                subs.append(session.declare_subscriber(topic_key(name, sensor), handler))
        self.ready = len(hubs)
        return subs


#: The batch header (README, Zenoh section): magic, version, sensor id, header size,
#: first sequence number, count, body size, stamp.
BATCH = struct.Struct("<4sBBHQIId")


class _BatchReader:
    """A Zenoh subscriber's callback for one hub sensor: sequence gaps, duplicates,
    latency (on Zenoh's thread: it never raises there)."""

    def __init__(self, laptop: Laptop, sensor: str) -> None:
        from robocli.protocols.ros4mat.codec import record_dtype

        self.laptop = laptop
        self.sensor = sensor
        self.dtype = record_dtype(sensor)
        self.next: int | None = None

    def __call__(self, sample: Any) -> None:
        received = time.time()
        try:
            data = sample.payload.to_bytes()
            magic, _v, _sid, head, first, count, size, _stamp = BATCH.unpack_from(data, 0)
            if magic != b"RCZB":
                raise ValueError(f"not a robocli batch: {magic!r}")
            body = memoryview(data)[head : head + size]
            hub_t = np.frombuffer(body, dtype=self.dtype, count=count)["t"]
            if self.sensor == "camera":
                _decode_frames(body, self.dtype, hub_t, count)
            lost = dup = 0
            if self.next is not None:
                lost = max(0, first - self.next)
                dup = max(0, min(self.next, first + count) - first)
            self.next = max(self.next or 0, first + count)
            if not self.laptop.counting.is_set():
                return
            with self.laptop.lock:
                t = self.laptop.tally(self.sensor)
                t.add(hub_t, received, lost, len(data))
                t.duplicates += dup
        except Exception as exc:
            with self.laptop.lock:
                if len(self.laptop.errors) < 20:
                    self.laptop.errors.append(f"{self.sensor}: {type(exc).__name__}: {exc}")


def _decode_frames(body: memoryview, dtype: Any, hub_t: Any, count: int) -> None:
    """Decode the batch's JPEG frames, as a student's program would (and as the ros4mat
    client does), so that the laptops' CPU compares."""
    from robocli.devices.hub.decode import decode_jpeg

    info = np.frombuffer(body, dtype=dtype, count=count)
    offset = dtype.itemsize * count
    for n in info["size_data"].tolist():
        decode_jpeg(bytes(body[offset : offset + n]))
        offset += n


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m robocli.bench.lab.laptop")
    ap.add_argument("--mode", choices=["tcp", "zenoh"], default="tcp")
    ap.add_argument("--hubs", required=True, help="HOST:PORT,... (tcp) or names (zenoh)")
    ap.add_argument("--router", default="", help="zenoh: the router (endpoint or config)")
    ap.add_argument("--camera", type=int, default=0, help="index of the robot watched")
    ap.add_argument("--poll", type=int, default=25, help="pulls per second and sensor")
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    hubs = a.hubs.split(",")
    laptop = Laptop()
    threads = []
    keep: list[Any] = []
    if a.mode == "zenoh":
        keep = laptop.zenoh_clients(a.router, hubs, a.camera)
    for i, address in enumerate(hubs if a.mode == "tcp" else []):
        sensors = ["imu", "adc"] + (["camera"] if i == a.camera else [])
        th = threading.Thread(target=laptop.tcp_client, args=(address, sensors, a.poll),
                              daemon=True)  # fmt: skip
        th.start()
        threads.append(th)
    while laptop.ready < len(hubs):
        time.sleep(0.02)
    print("ready", flush=True)
    started = stopped = 0.0
    for line in sys.stdin:
        if line.strip() == "go":
            started = time.time()
            laptop.counting.set()
        elif line.strip() == "stop":
            break
    stopped = time.time()
    laptop.counting.clear()
    laptop.stopping.set()
    for th in threads:
        th.join(10.0)
    for sub in reversed(keep):
        with contextlib.suppress(Exception):
            (sub.undeclare if hasattr(sub, "undeclare") else sub.close)()
    with laptop.lock:
        result = {
            "seconds": stopped - started if started else 0.0,
            "sensors": {s: t.report() for s, t in laptop.tallies.items()},
            "errors": laptop.errors,
        }
    with open(a.out, "w") as f:
        json.dump(result, f)
    return 0


if __name__ == "__main__":
    sys.exit(main())
