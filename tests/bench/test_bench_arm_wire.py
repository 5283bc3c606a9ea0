"""``bench rtt|jitter --target arm`` reach a big-endian or FLOAT64 controller:
``--byte-order`` and ``--real-size``, as the other arm commands take them (issue 13: 19)."""

from __future__ import annotations

import json
import socket
from collections.abc import Iterator

import pytest

from robocli.errors import TransportError
from robocli.sim.abb.server import AbbSim
from tests.commands.helpers import one_line_error, run


@pytest.fixture(scope="module")
def big_float64() -> Iterator[int]:
    """An ABB simulator speaking big-endian Simple Message with 8-byte reals, on a motion
    port whose state port is 2 above (what ``--url HOST:MOTION_PORT`` reaches); yields the
    motion port."""
    for _ in range(50):
        with socket.socket() as probe:  # a free port now; retried if taken before we bind
            probe.bind(("127.0.0.1", 0))
            motion = probe.getsockname()[1]
        if motion > 65533:
            continue
        sim = AbbSim(state_ms=10.0, byteorder=">", real=8)
        try:
            sim.serve_tcp("127.0.0.1", motion, motion + 2)
        except TransportError:
            sim.close()
            continue
        with sim:
            yield motion
        return
    pytest.fail("no two free ports 2 apart on 127.0.0.1")


@pytest.mark.parametrize("kind", ["rtt", "jitter"])
def test_the_arm_benches_reach_a_big_endian_float64_controller(kind: str, big_float64: int) -> None:
    extra = ["--floor-n", "10"] if kind == "rtt" else []
    proc = run("bench", kind, "--target", "arm", f"127.0.0.1:{big_float64}",
               "--byte-order", "big", "--real-size", "8", "-n", "10", "--json", *extra,
               timeout=120)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    measured = [r for r in json.loads(proc.stdout) if "floor" not in r["name"]
                and not r.get("reference")]  # fmt: skip
    assert len(measured) == 1 and measured[0]["n"] == 10, measured
    assert "big-endian, 64-bit reals" in measured[0]["where"]


def test_the_bench_simulator_speaks_the_variant_asked_for() -> None:
    proc = run("bench", "jitter", "--target", "arm", "--byte-order", "big", "--real-size", "8",
               "-n", "10", "--json", timeout=120)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    period = next(r for r in json.loads(proc.stdout) if r["name"] == "state period")
    assert period["n"] == 10 and "ABB simulator process, big-endian" in period["where"]


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (("jitter", "--byte-order", "big"), "--byte-order is for --target arm"),
        (("rtt", "--target", "hub", "--real-size", "8"), "--real-size is for --target arm"),
        (("jitter", "--target", "arm", "--byte-order", "middle"), "'middle'"),
        (("rtt", "--target", "arm", "--real-size", "2"), "'2' is not one of '4', '8'"),
    ],
)
def test_wire_options_outside_an_arm_target_are_usage_errors(
    args: tuple[str, ...], named: str
) -> None:
    line = one_line_error(run("bench", *args), 2)
    assert named in line, line
