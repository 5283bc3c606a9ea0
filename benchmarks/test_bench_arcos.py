"""ARCOS SIP stream: construct alone vs the C framer (+ the struct fast path the client uses).

The same stream of real recorded SIPs is parsed three ways in one process; the ratios are
what the targets speak of (`C framer >= 50 x construct`). Run with `make bench`.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from robocli.core import Framer
from robocli.io.capture import read_capture
from robocli.protocols import arcos

TRACE = (
    Path(__file__).resolve().parents[1]
    / "tests"
    / "data"
    / "arcos"
    / "b_simpleMotionCommands.jsonl"
)


@pytest.fixture(scope="module")
def stream() -> tuple[bytes, int]:
    sips = [f.frame for f in read_capture(TRACE) if f.direction == "rx" and f.frame[3] == 0x32]
    frames = (sips * (20_000 // len(sips) + 1))[:20_000]
    return b"".join(frames), len(frames)


def parse_with_construct(data: bytes) -> int:
    n = pos = 0
    view = memoryview(data)
    while pos < len(data):
        frame = arcos.Frame.parse(view[pos:])
        arcos.SIP.parse(frame.payload[1:])
        pos += frame.count + 3
        n += 1
    return n


def parse_with_c_framer(data: bytes) -> int:
    return Framer("arcos").count(data, 4096)


def parse_like_the_client(data: bytes) -> int:
    framer = Framer("arcos")
    n = 0
    for pos in range(0, len(data), 4096):
        for frame in framer.feed(data[pos : pos + 4096]):
            arcos.decode_sip(memoryview(frame)[4:-2])
            n += 1
    return n


def _best(fn, data: bytes, repeat: int = 3) -> float:  # type: ignore[no-untyped-def]
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        fn(data)
        best = min(best, time.perf_counter() - start)
    return best


def test_sip_stream_ratios(benchmark, stream: tuple[bytes, int]) -> None:  # type: ignore[no-untyped-def]
    data, n = stream
    assert benchmark(parse_with_c_framer, data) == n
    small = data[: 89 * 2000]
    t_construct = _best(parse_with_construct, small, 1) * (n / 2000)
    t_c = _best(parse_with_c_framer, data)
    t_client = _best(parse_like_the_client, data)
    info = {
        "frames": n,
        "construct_frames_per_s": n / t_construct,
        "c_framer_frames_per_s": n / t_c,
        "client_path_frames_per_s": n / t_client,
        "c_framer_x_construct": t_construct / t_c,
        "client_path_x_construct": t_construct / t_client,
    }
    benchmark.extra_info.update(info)
    print("\n" + "\n".join(f"{k}: {v:,.1f}" for k, v in info.items()))
