"""Laser benchmarks through the real client: the period of streamed scans as the client
receives them (reception jitter) and as the sensor stamps them, the delay from a scan's
step 0 (its stamp on the host clock) to its reception, and the client's decode time per
frame (the pure-Python scan decode against the sensor's period)."""

from __future__ import annotations

import contextlib
import time
from typing import Any

import numpy as np

from robocli.bench.stats import Progress


def laser_scan_timing(
    url: str, n: int, *, progress: Progress | None = None, into: dict[str, Any] | None = None
) -> dict[str, Any]:
    """Stream ``n`` + 1 full scans (MD) from the laser at ``url``; seconds per sample:
    ``period`` (reception intervals), ``stamp_period`` (sensor stamp intervals), ``delay``
    (reception - stamp on the host clock) and ``decode`` (one frame's decode, measured on
    the last frame's bytes after the stream). Partial results stay in ``into`` (Ctrl-C)."""
    from robocli.devices.laser import Laser
    from robocli.protocols.scip2 import fast

    out = into if into is not None else {}
    received: list[float] = []
    stamps: list[int] = []
    delays: list[float] = []
    last: list[bytes] = []

    def keep(direction: str, payload: bytes, t: float) -> None:
        if direction == "rx" and payload[:1] == b"M":
            last[:] = [payload]

    try:
        with Laser.connect(url, listeners=[keep]) as laser:
            with contextlib.closing(laser.scans(n + 1)) as scans:  # QT now, not at collection
                for i, scan in enumerate(scans):
                    received.append(scan.received)
                    stamps.append(scan.stamp_ms)
                    delays.append(scan.received - scan.t)
                    if progress is not None:
                        progress(i + 1)
    finally:
        out["period"] = np.diff(np.array(received))
        out["stamp_period"] = np.diff(np.array(stamps, dtype=np.float64)) / 1000.0
        out["delay"] = np.array(delays)
    if last:
        frame = last[0]
        samples = np.empty(50)
        for k in range(len(samples)):
            start = time.perf_counter()
            fast.decode_scan(frame)
            samples[k] = time.perf_counter() - start
        out["decode"] = samples
    return out
