"""Hokuyo SCIP 2.0 scan decode: the C decoder vs construct and the pure-Python reference.

One UTM-30LX scan (1081 steps, 3-char ranges, an MD frame) and one ME frame (range +
intensity) are decoded three ways in the same process. The target is the share of one core
a 40 Hz stream of such scans takes: well under 1 %. Run with `make bench`.
"""

from __future__ import annotations

import random
import time
from collections.abc import Callable
from typing import Any

import construct as cs
import pytest

from robocli.protocols import scip2
from robocli.protocols.scip2 import fast

STEPS = 1081  # UTM-30LX: steps 0..1080, 0.25 deg, 270 deg
RATE_HZ = 40  # 2400 rpm


def _frame(command: str, intensity: bool) -> bytes:
    rnd = random.Random(30)
    ranges = [
        rnd.choice([1, 2, 3]) if rnd.random() < 0.05 else rnd.randint(23, 60000)
        for _ in range(STEPS)
    ]
    ints = [rnd.randint(0, 20000) for _ in range(STEPS)] if intensity else None
    echo = scip2.build_request(command, start=0, end=STEPS - 1, count=0)[:-1]
    return scip2.build_scan(echo, "99", 123456, ranges, ints)


@pytest.fixture(scope="module", params=["MD", "ME"])
def frame(request: pytest.FixtureRequest) -> tuple[str, bytes]:
    return request.param, _frame(request.param, request.param == "ME")


def decode_with_construct(block: bytes) -> Any:
    """Lines split and checked in Python, the stream parsed by a construct array."""
    reply, echo, ts = scip2.scan_header(block)
    payload = scip2.join_data_lines(reply.body[1:])
    per = 2 if echo.intensity else 1
    return cs.Array(echo.count * per, scip2.Enc3).parse(payload)


def _best(fn: Callable[[bytes], Any], block: bytes, n: int, repeat: int = 5) -> float:
    """Best of ``repeat`` runs of ``n`` calls: seconds per call."""
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        for _ in range(n):
            fn(block)
        best = min(best, (time.perf_counter() - start) / n)
    return best


def test_scan_decode(benchmark: Any, frame: tuple[str, bytes]) -> None:
    command, block = frame
    scan = benchmark(fast.decode_scan, block)
    assert len(scan.ranges) == STEPS
    ref = scip2.decode_scan(block)
    assert scan.ranges.tolist() == ref.ranges.tolist()
    t_c = _best(fast.decode_scan, block, 2000)
    reply, echo, _ = scip2.scan_header(block)
    at = block.index(b"\n", block.index(b"\n", block.index(b"\n") + 1) + 1) + 1
    region = block[at:-1]
    per = 2 if echo.intensity else 1
    t_kernel = _best(lambda b: fast.decode_data(b, 3, STEPS * per), region, 2000)
    t_ref = _best(scip2.decode_scan, block, 20, 3)
    t_construct = _best(decode_with_construct, block, 10, 3)
    info = {
        "frame_bytes": len(block),
        "c_us_per_scan": t_c * 1e6,
        "c_kernel_us_per_scan": t_kernel * 1e6,
        "pure_python_us_per_scan": t_ref * 1e6,
        "construct_us_per_scan": t_construct * 1e6,
        "c_share_of_core_at_40Hz_pct": t_c * RATE_HZ * 100,
        "pure_python_share_at_40Hz_pct": t_ref * RATE_HZ * 100,
        "c_x_pure_python": t_ref / t_c,
        "c_x_construct": t_construct / t_c,
    }
    benchmark.extra_info.update(info)
    print(f"\n{command} ({STEPS} steps):\n" + "\n".join(f"{k}: {v:,.2f}" for k, v in info.items()))
