"""A hub serving IMU 200 Hz + ADC 1 kHz to N subscribers: the hub's CPU (cores) and the
bytes it writes, over ros4mat TCP and over Zenoh (directly, and through a router).

    python benchmarks/zenoh_hub.py --subscribers 1 10 --seconds 10

The hub (``robocli serve --sim``) and the router run in their own processes; the N
subscribers share one other process (N Zenoh sessions or N TCP connections), each reading
both sensors every 50 ms. Hub CPU from /proc/PID/stat, bytes from the hub's TCP sockets
(``ss -tip``: bytes_sent of the connections open at both ends of the measure; clients stay
connected throughout). The delay: receive time minus the acquisition time of the newest ADC
sample, one host clock (Zenoh: as each batch arrives, in the first client's session;
ros4mat: at each 50 ms read). Linux only. Prints one row per run.
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

SENSORS = {"adc": 1000, "imu": 200}
CAMERA_ENV = "ROBOCLI_BENCH_CAMERA"  #: "1": also a 320x240 JPEG camera at 15 fps
READ_PERIOD_S = 0.05
CLK = os.sysconf("SC_CLK_TCK")


def free_endpoint() -> str:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{s.getsockname()[1]}"


def cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK


def sent_bytes(pid: int) -> int:
    """Bytes the TCP sockets of process ``pid`` have sent so far (``ss -tip``)."""
    out = subprocess.run(["ss", "-tinpH"], capture_output=True, text=True, timeout=30).stdout
    total, mine = 0, False
    for line in out.splitlines():
        if not line.startswith(("\t", " ")):
            mine = f"pid={pid}," in line
        elif mine:
            for field in line.split():
                if field.startswith("bytes_sent:"):
                    total += int(field.split(":")[1])
    return total


def robocli(*args: str, out: int | None = subprocess.DEVNULL) -> subprocess.Popen[bytes]:
    return subprocess.Popen([sys.executable, "-m", "robocli", *args], stdout=out,
                            stderr=subprocess.DEVNULL)  # fmt: skip


def wait_line(proc: subprocess.Popen[bytes], needle: bytes, timeout: float = 60.0) -> None:
    end = time.monotonic() + timeout
    assert proc.stdout is not None
    while time.monotonic() < end:
        line = proc.stdout.readline()
        if needle in line:
            return
    raise RuntimeError(f"{needle!r} not printed")


def subscribers_main(mode: str, where: str, n: int, seconds: float) -> None:
    """The subscriber process: N clients, each reading both sensors; one JSON line out."""
    from robocli.devices.hub.client import Hub
    from robocli.devices.hub.over_zenoh import ZenohHub

    camera = os.environ.get(CAMERA_ENV) == "1"
    sensors = [*SENSORS, "camera"] if camera else list(SENSORS)
    clients: list[Hub] = []
    for i in range(n):
        if mode == "ros4mat":
            hub = Hub.connect(where)
            for sensor, rate in SENSORS.items():
                hub.subscribe(sensor, rate, buffer=rate * 2)
            if camera:
                hub.subscribe("camera", 15, quality=80, buffer=30)
        else:
            hub = ZenohHub.connect("bench", zenoh=where, history=False)
            for sensor in SENSORS:
                hub.subscribe(sensor)
            if camera and i == 0:
                hub.subscribe("camera", 15, quality=80)
            elif camera:
                hub.subscribe("camera")
        clients.append(hub)
    delays: list[float] = []  # receive time - acquisition time of a batch's last ADC sample
    if mode != "ros4mat":
        first = clients[0]
        assert isinstance(first, ZenohHub)

        def on_batch(sample: Any) -> None:
            now = time.time()
            raw = sample.payload.to_bytes()
            delays.append(now - float(np.frombuffer(raw, "<f8", 1, len(raw) - 8)[0]))

        first.zsession.declare_subscriber("robocli/bench/adc", on_batch)
    print("ready", flush=True)
    got = {s: 0 for s in sensors}
    end = time.monotonic() + seconds + 2.0  # the parent measures `seconds` in the middle
    while time.monotonic() < end:
        for hub in clients:
            for sensor in sensors:
                reading = hub.read(sensor)
                got[sensor] += len(reading)
                if mode == "ros4mat" and hub is clients[0] and sensor == "adc" and len(reading):
                    delays.append(time.time() - float(reading.t[-1]))
        time.sleep(READ_PERIOD_S)
    lost = sum(sum(h.lost.values()) for h in clients)
    dup = sum(sum(getattr(h, "duplicates", {}).values()) for h in clients)
    for hub in clients:
        hub.close()
    ms = np.percentile(delays, [50, 99]) * 1e3 if delays else [float("nan")] * 2
    delay = [round(float(x), 1) for x in ms]
    out = {"samples": got, "lost": lost, "duplicates": dup, "delay_ms_p50_p99": delay}
    print(json.dumps(out), flush=True)


def run(mode: str, n: int, seconds: float) -> dict[str, object]:
    publish = ",".join(f"{s}={r}" for s, r in SENSORS.items())
    procs: list[subprocess.Popen[bytes]] = []
    try:
        if mode == "ros4mat":
            port = free_endpoint().rsplit(":", 1)[1]
            hub = robocli("serve", "--sim", "--port", port, out=subprocess.PIPE)
            where = f"127.0.0.1:{port}"
        else:
            hub_ep = free_endpoint()
            spec = hub_ep
            where = hub_ep
            if mode == "zenoh-router":
                router_ep = free_endpoint()
                router = robocli("router", "--listen", router_ep, out=subprocess.PIPE)
                procs.append(router)
                wait_line(router, b"zenoh router")
                cfg = Path(tempfile.mkdtemp()) / "hub.json5"
                cfg.write_text(json.dumps({
                    "mode": "peer", "connect": {"endpoints": [router_ep]},
                    "listen": {"endpoints": [hub_ep]},
                    "scouting": {"multicast": {"enabled": False}},
                    "transport": {"shared_memory": {"enabled": False}},
                }))  # fmt: skip
                spec, where = str(cfg), router_ep
            hub = robocli("serve", "--sim", "--no-tcp", "--zenoh", spec, "--name", "bench",
                          "--publish", publish, out=subprocess.PIPE)  # fmt: skip
        procs.append(hub)
        wait_line(hub, b"hub serving")
        subs = subprocess.Popen(
            [sys.executable, __file__, "--_subscribers", mode, where, str(n), str(seconds)],
            stdout=subprocess.PIPE,
        )
        procs.append(subs)
        wait_line(subs, b"ready", 120.0)
        time.sleep(1.0)  # settle
        c0, w0, t0 = cpu_s(hub.pid), sent_bytes(hub.pid), time.monotonic()
        time.sleep(seconds)
        c1, w1, t1 = cpu_s(hub.pid), sent_bytes(hub.pid), time.monotonic()
        assert subs.stdout is not None
        result = json.loads(subs.stdout.readline() or b"{}")
        subs.wait(60)
        return {
            "mode": mode, "subscribers": n, "hub_cores": round((c1 - c0) / (t1 - t0), 3),
            "hub_kB_per_s": round((w1 - w0) / (t1 - t0) / 1e3, 1), **result,
        }  # fmt: skip
    finally:
        for p in reversed(procs):
            if p.poll() is None:
                p.terminate()
                try:
                    p.wait(20)
                except subprocess.TimeoutExpired:
                    p.kill()


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--_subscribers":
        subscribers_main(sys.argv[2], sys.argv[3], int(sys.argv[4]), float(sys.argv[5]))
        return
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--subscribers", type=int, nargs="+", default=[1, 10])
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--modes", nargs="+", default=["ros4mat", "zenoh", "zenoh-router"])
    ap.add_argument("--camera", action="store_true", help="Also a 320x240 JPEG camera, 15 fps.")
    args = ap.parse_args()
    if args.camera:
        os.environ[CAMERA_ENV] = "1"
    for mode in args.modes:
        for n in args.subscribers:
            print(json.dumps(run(mode, n, args.seconds)), flush=True)


if __name__ == "__main__":
    main()
