"""Benchmarks of the C core: framers, ring buffer, alignment (pytest-benchmark).

Targets (shared/targets.md): >= 1 M frames/s in C; ring push <= 100 ns/record;
8 streams x 1 M samples aligned onto a 1 M-point timeline <= 100 ms.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from robocli.core import Framer, Ring, align_linear, align_nearest, arcos_checksum

N_SIP = 100_000
SIP_SIZE = 89  # FA FB 56 32 + 83 data bytes + 2 checksum bytes


def sip_stream(n: int) -> bytes:
    """``n`` ARCOS standard SIPs (type 0x32, 89 bytes each) back to back, random payloads.

    Shared by the construct comparison: parse the same stream with both.
    """
    rng = np.random.default_rng(42)
    payloads = rng.integers(0, 256, size=(n, 83), dtype=np.uint8)
    out = bytearray()
    for row in payloads:
        body = b"\x32" + row.tobytes()
        ck = arcos_checksum(body)
        out += b"\xfa\xfb\x56" + body + bytes((ck >> 8, ck & 0xFF))
    return bytes(out)


@pytest.fixture(scope="module")
def sips() -> bytes:
    return sip_stream(N_SIP)


def _rate(benchmark: Any, count: int, key: str) -> float:
    mean = float(benchmark.stats.stats.mean)
    benchmark.extra_info[key] = count / mean
    return mean


def test_c_framer_count(benchmark: Any, sips: bytes) -> None:
    """(a) C framer, count API, whole stream in one feed."""
    got = benchmark(lambda: Framer("arcos").count(sips))
    assert got == N_SIP
    _rate(benchmark, N_SIP, "frames_per_s")


def test_c_framer_count_chunked(benchmark: Any, sips: bytes) -> None:
    """(a') C framer, count API, 4 KiB chunks as a socket would deliver them."""
    got = benchmark(lambda: Framer("arcos").count(sips, 4096))
    assert got == N_SIP
    _rate(benchmark, N_SIP, "frames_per_s")


def test_python_framer_feed(benchmark: Any, sips: bytes) -> None:
    """(b) Framer.feed from Python in 4 KiB chunks, one bytes object per frame."""

    def run() -> int:
        f = Framer("arcos")
        n = 0
        for i in range(0, len(sips), 4096):
            n += len(f.feed(sips[i : i + 4096]))
        return n

    assert benchmark.pedantic(run, rounds=5, iterations=1, warmup_rounds=1) == N_SIP
    _rate(benchmark, N_SIP, "frames_per_s")


N_REC = 1_000_000
REC = 40


@pytest.fixture(scope="module")
def records() -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(N_REC, dtype=np.float64) * 1e-3
    rec = np.random.default_rng(0).integers(0, 256, size=(N_REC, REC), dtype=np.uint8)
    return t, rec


def test_ring_push_many(benchmark: Any, records: tuple[np.ndarray, np.ndarray]) -> None:
    """(c) push_many of 1 M 40-byte records into a 1 M ring with 4 readers."""
    t, rec = records
    ring = Ring(REC, N_REC)
    for _ in range(4):
        ring.add_reader()
    benchmark.pedantic(lambda: ring.push_many(t, rec), rounds=10, iterations=1, warmup_rounds=1)
    benchmark.extra_info["ns_per_record"] = float(benchmark.stats.stats.mean) / N_REC * 1e9


def test_ring_push_single(benchmark: Any, records: tuple[np.ndarray, np.ndarray]) -> None:
    """(c') Ring.push one record at a time from Python (includes the Python call)."""
    t, rec = records
    n = 100_000
    items = [rec[i].tobytes() for i in range(n)]
    ring = Ring(REC, 1 << 16)
    ring.add_reader()

    def run() -> None:
        push = ring.push
        for i in range(n):
            push(i * 1e-3, items[i])

    benchmark.pedantic(run, rounds=3, iterations=1)
    benchmark.extra_info["ns_per_record"] = float(benchmark.stats.stats.mean) / n * 1e9


def test_ring_read_all(benchmark: Any, records: tuple[np.ndarray, np.ndarray]) -> None:
    """(c'') read of 1 M new records into fresh NumPy arrays."""
    t, rec = records
    ring = Ring(REC, N_REC)
    reader = ring.add_reader()

    def setup() -> tuple[tuple[Any, ...], dict[str, Any]]:
        ring.push_many(t, rec)
        return (), {}

    def run() -> int:
        return int(ring.read(reader)[0].shape[0])

    benchmark.pedantic(run, setup=setup, rounds=10, iterations=1, warmup_rounds=1)
    benchmark.extra_info["ns_per_record"] = float(benchmark.stats.stats.mean) / N_REC * 1e9
    out_t, out_rec = ring.read(reader)
    assert out_t.shape == (0,)


K_STREAMS = 8
M_REF = 1_000_000


@pytest.fixture(scope="module")
def timelines() -> tuple[list[np.ndarray], np.ndarray]:
    rng = np.random.default_rng(3)
    streams = [np.sort(rng.uniform(0.0, 1000.0, M_REF)) for _ in range(K_STREAMS)]
    ref = np.linspace(0.0, 1000.0, M_REF)
    return streams, ref


def test_align_nearest_8x1m(benchmark: Any, timelines: tuple[list[np.ndarray], np.ndarray]) -> None:
    """(d) 8 streams x 1 M samples onto a 1 M-point timeline, nearest within 5 ms."""
    streams, ref = timelines
    out = benchmark.pedantic(
        lambda: align_nearest(streams, ref, 0.005), rounds=5, iterations=1, warmup_rounds=1
    )
    assert out.shape == (K_STREAMS, M_REF)
    benchmark.extra_info["ms_total"] = float(benchmark.stats.stats.mean) * 1e3


def test_align_linear_8x1m(benchmark: Any, timelines: tuple[list[np.ndarray], np.ndarray]) -> None:
    """(d') the same with linear-interpolation indices and weights."""
    streams, ref = timelines
    idx, w = benchmark.pedantic(
        lambda: align_linear(streams, ref), rounds=5, iterations=1, warmup_rounds=1
    )
    assert idx.shape == w.shape == (K_STREAMS, M_REF)
    benchmark.extra_info["ms_total"] = float(benchmark.stats.stats.mean) * 1e3
