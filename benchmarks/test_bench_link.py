"""Link timing figures of the README that pytest-benchmark can hold: the C ping-pong floor
pinned both ways, and the simulator's SIP period seen by a bare socket reader.

The client's own round trips are measured by `robocli bench rtt` (floor, C responder,
simulator process, with Ctrl-C and progress), which reuses the same functions.
"""

from __future__ import annotations

from typing import Any

import pytest

from robocli.bench.harness import allowed_cpus, c_floor
from robocli.bench.pioneer import raw_sip_periods
from robocli.bench.stats import Run, SampleStats


@pytest.mark.parametrize("placement", ["same CPU", "different CPUs"])
def test_c_floor_pinned(benchmark: Any, placement: str) -> None:
    cpus = allowed_cpus()
    if placement == "different CPUs" and len(cpus) < 2:
        pytest.skip("one CPU only")
    cpu = cpus[0] if cpus else None
    echo = cpus[1] if placement == "different CPUs" else cpu
    runs: list[Run] = []

    def measure() -> None:
        runs.append(c_floor(Run("floor", 20_000), cpu, echo))

    benchmark.pedantic(measure, rounds=3, iterations=1)
    medians = [SampleStats.of(r.values).median * 1e6 for r in runs]
    benchmark.extra_info["median_us"] = medians
    benchmark.extra_info["p99_us"] = [SampleStats.of(r.values).p99 * 1e6 for r in runs]


def test_sim_sip_period_raw_reader(benchmark: Any) -> None:
    from robocli.sim.pioneer.server import PioneerSim

    with PioneerSim() as sim:
        url = sim.serve_tcp("127.0.0.1", 0)
        host, port = url.removeprefix("tcp://").rsplit(":", 1)
        run = benchmark.pedantic(lambda: raw_sip_periods(host, int(port), 200), rounds=1)
    stats = SampleStats.of(run.values)
    assert run.complete
    benchmark.extra_info.update(period_ms=stats.mean * 1e3, std_ms=stats.std * 1e3)
