"""Sensor hub client: zero-copy decoding against construct, the empty-pull round trip, and
the many-client throughput target (40 clients x IMU 200 Hz, ADC 1 kHz, laser 1081 beams
40 Hz, camera 320x240 30 Hz, each pulled at 20 Hz: no loss, p99 pull <= 5 ms, hub <= 1
core). The hub runs in its own process. Run with `make bench`."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from robocli import hub_bench
from robocli.devices.hub import Hub
from robocli.devices.hub_decode import decode_reading
from robocli.protocols import ros4mat as r4m


@pytest.fixture(scope="module")
def hub_proc() -> Iterator[tuple[str, int]]:
    with hub_bench.hub_process() as (url, pid):
        yield url.removeprefix("tcp://"), pid


def _adc_reply(n: int) -> bytes:
    rng = np.random.default_rng(0)
    return r4m.encode_records(
        "adc", [{"channels": list(rng.random(8)), "t": i / 1000} for i in range(n)]
    )


def test_decode_adc_50_zero_copy(benchmark: pytest.FixtureRequest) -> None:
    frame = _adc_reply(50)
    reading = benchmark(decode_reading, frame, "adc")
    assert reading.data.shape == (8, 50)


def test_decode_adc_50_construct(benchmark: pytest.FixtureRequest) -> None:
    frame = _adc_reply(50)
    msg = benchmark(r4m.decode, frame)
    assert len(msg.body) == 50


def test_empty_pull_rtt(benchmark: pytest.FixtureRequest, hub_proc: tuple[str, int]) -> None:
    with Hub.connect(hub_proc[0]) as hub:
        hub.subscribe("gps", 1)
        frame = benchmark(hub.pull, "gps")
        assert frame[0] == r4m.MsgType.GPS
