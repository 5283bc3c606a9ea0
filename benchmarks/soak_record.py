"""Soak `robocli record --hub` for the hub's full sensor set (``make soak-record``).

A ``robocli serve --sim`` and a ``robocli record --hub ... --sensors imu,adc,laser,camera``
run as two processes for ``--minutes`` (default 10). Every ``--every`` seconds the
recorder's CPU time and resident memory are read from /proc and the file's size is noted.
At the end the recording's chunk indexes give its size per minute as written (zstd) and
before compression (each chunk's uncompressed size), and its summary the messages per
channel. Prints a report (and ``--json`` it); exits 1 when messages were dropped.

Usage: python benchmarks/soak_record.py [--minutes 10] [--every 10] [--out DIR] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

SENSORS = "imu,adc,laser,camera"
#: The rates the sensor set is recorded at (robocli record's defaults for these sensors).
RATES = {"imu": 200, "adc": 1000, "laser": 40, "camera": 30}
TICK = os.sysconf("SC_CLK_TCK")


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK  # utime + stime


def _rss_mb(pid: int) -> float:
    status = Path(f"/proc/{pid}/status").read_text()
    found = re.search(r"VmRSS:\s+(\d+) kB", status)
    return int(found.group(1)) / 1024 if found else float("nan")


def _serve(robocli: list[str]) -> tuple[subprocess.Popen[str], str]:
    proc = subprocess.Popen(
        [*robocli, "serve", "--sim", "--port", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    assert proc.stdout is not None
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        found = re.search(r"tcp://([\d.]+:\d+)", line)
        if found:
            return proc, found.group(1)
        if not line and proc.poll() is not None:
            break
    proc.kill()
    raise SystemExit("soak: serve --sim did not start")


def _per_minute(path: Path, start_ns: int) -> list[dict[str, float]]:
    """Bytes per minute of recording (by chunk start time): compressed and uncompressed."""
    from mcap.reader import make_reader

    minutes: dict[int, dict[str, float]] = {}
    with path.open("rb") as fh:
        summary = make_reader(fh).get_summary()
        assert summary is not None
        for chunk in summary.chunk_indexes:
            m = int((chunk.message_start_time - start_ns) // 60_000_000_000)
            row = minutes.setdefault(m, {"minute": m + 1, "zstd_mb": 0.0, "uncompressed_mb": 0.0})
            row["zstd_mb"] += chunk.compressed_size / 1e6
            row["uncompressed_mb"] += chunk.uncompressed_size / 1e6
    return [minutes[k] for k in sorted(minutes)]


def _acquired(topic: str, span_s: float) -> int:
    """Samples a sensor acquired in ``span_s`` at its rate."""
    return round(RATES.get(topic.rsplit("/", 1)[-1], 0) * span_s) + 1


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--every", type=float, default=10.0, help="Sampling period, s.")
    ap.add_argument("--out", type=Path, default=None, help="Folder for the recording.")
    ap.add_argument("--json", type=Path, default=None, help="Write the report here too.")
    ap.add_argument("--keep", action="store_true", help="Keep the recording.")
    args = ap.parse_args()
    robocli = [sys.executable, "-m", "robocli"]
    folder = args.out or Path(tempfile.mkdtemp(prefix="soak-record-"))
    folder.mkdir(parents=True, exist_ok=True)
    out = folder / "soak.mcap"
    seconds = args.minutes * 60
    server, address = _serve(robocli)
    samples: list[dict[str, float]] = []
    try:
        rec = subprocess.Popen(
            [
                *robocli,
                "record",
                "--hub",
                address,
                "--sensors",
                SENSORS,
                "--duration",
                f"{seconds:g}",
                "-o",
                str(out),
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        assert rec.stderr is not None
        rec.stderr.readline()  # "recording to ...": connected and subscribed
        t0, cpu0 = time.monotonic(), _cpu_s(rec.pid)
        last_t, last_cpu = t0, cpu0
        while rec.poll() is None:
            time.sleep(min(args.every, max(0.1, t0 + seconds + 30 - time.monotonic())))
            try:
                now, cpu, rss = time.monotonic(), _cpu_s(rec.pid), _rss_mb(rec.pid)
            except (FileNotFoundError, ProcessLookupError):
                break
            if rss != rss:  # exited between the two reads (a zombie has no memory)
                break
            samples.append(
                {
                    "t_s": round(now - t0, 1),
                    "rss_mb": round(rss, 1),
                    "cpu_cores": round((cpu - last_cpu) / (now - last_t), 3),
                    "file_mb": round(out.stat().st_size / 1e6, 2),
                }
            )
            print(f"soak: {samples[-1]}", flush=True)
            last_t, last_cpu = now, cpu
            if now - t0 > seconds + 120:
                rec.send_signal(signal.SIGINT)
        wall = time.monotonic() - t0
        tail = rec.stderr.read()
        rc = rec.wait(60)
    finally:
        server.send_signal(signal.SIGINT)
        try:
            server.wait(30)
        except subprocess.TimeoutExpired:
            server.kill()
    from robocli.io.record import info

    summary = info(out)
    result = summary.as_dict()
    dropped = re.search(r"(\d+) dropped", tail)
    channels = {c["topic"]: c for c in result["channels"]}
    rss = [s["rss_mb"] for s in samples if s["t_s"] <= seconds]
    steady = rss[len(rss) // 5 :] or rss  # after the first fifth: the buffers have grown
    report: dict[str, Any] = {
        "minutes": args.minutes, "exit_code": rc, "stderr": tail.strip(),
        "dropped": int(dropped.group(1)) if dropped else 0,
        "messages": result["messages"], "file_mb": round(out.stat().st_size / 1e6, 1),
        "cpu_cores_mean": round(sum(s["cpu_cores"] for s in samples) / max(1, len(samples)), 3),
        "cpu_cores_max": max((s["cpu_cores"] for s in samples), default=0.0),
        "rss_mb_first": rss[0] if rss else None, "rss_mb_last": rss[-1] if rss else None,
        "rss_mb_steady_min": min(steady, default=None),
        "rss_mb_steady_max": max(steady, default=None),
        "per_minute": _per_minute(out, summary.start_ns),
        "channels": {
            topic: {"count": c["count"], "rate_hz": c["rate_hz"],
                    "largest_gap_s": c["largest_gap_s"],
                    # samples the hub acquired in the recording's span: what was not recorded
                    # was lost before the recorder (the hub's buffer overflowed between pulls)
                    "acquired": _acquired(topic, c["last"] - c["first"])}
            for topic, c in channels.items() if "/raw/" not in topic
        },
        "expected_rates_hz": RATES, "wall_s": round(wall, 1), "samples": samples,
    }  # fmt: skip
    text = json.dumps(report, indent=2)
    print(text)
    if args.json is not None:
        args.json.write_text(text + "\n")
    if not args.keep and args.out is None:
        out.unlink()
        folder.rmdir()
    return 1 if report["dropped"] or rc != 0 else 0


if __name__ == "__main__":
    raise SystemExit(main())
