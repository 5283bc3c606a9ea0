"""The virtual serial port's added round trip (robocli.bench.serial): 2-byte commands and
80-byte replies (the Create's group 100 packet) echoed by a device on the hub's serial port,
on a local pty alone, through the hub, and through the hub behind a local pty. The Create's
sensor stream (one packet per 15 ms) is the yardstick; docs/serial.md gives the figures."""

from __future__ import annotations

import os
from typing import Any

import pytest

from robocli.bench.serial import PATHS, serial_latency

pytestmark = pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs pseudo-terminals")


@pytest.mark.parametrize("size", [2, 80])
def test_serial_round_trip(benchmark: Any, size: int) -> None:
    results: list[dict[str, Any]] = []
    benchmark.pedantic(lambda: results.append(serial_latency(n=300, size=size)), rounds=1)
    (stats,) = results
    assert set(stats) == set(PATHS)
    for path, s in stats.items():
        benchmark.extra_info[f"{path}_median_ms"] = s.median * 1e3
        benchmark.extra_info[f"{path}_p99_ms"] = s.p99 * 1e3
    benchmark.extra_info["added_median_ms"] = (stats["hub+pty"].median - stats["pty"].median) * 1e3
