"""``robocli bench rtt|jitter --target arm``: Table-5 fields in the JSON, the simulator in its
own process or ``--url``, the paper-like model's latency floor; the round trips never move
the arm (ABB: download starts only; a streaming server: "stay here")."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import time
from typing import Any

import numpy as np
import pytest

from robocli.bench.arm import parse_url, rtt, state_periods
from robocli.bench.stats import Run
from robocli.errors import InvalidArgument
from robocli.sim.abb.server import AbbSim

BENCH = [sys.executable, "-m", "robocli", "bench"]
TABLE5 = {"n", "mean", "median", "std", "min", "max", "p90", "p99"}


def bench(*args: str) -> tuple[int, list[dict[str, Any]], str]:
    done = subprocess.run([*BENCH, *args, "--target", "arm", "--json"], capture_output=True,
                          text=True, timeout=60)  # fmt: skip
    return done.returncode, json.loads(done.stdout) if done.returncode == 0 else [], done.stderr


def by_name(results: list[dict[str, Any]], name: str) -> dict[str, Any]:
    return next(r for r in results if r["name"] == name)


def test_rtt_json_has_table5_fields_and_the_floor() -> None:
    code, results, err = bench("rtt", "--count", "30", "--floor-n", "30")
    assert code == 0, err
    r = by_name(results, "JOINT_TRAJ_PT -> reply")
    assert TABLE5 <= set(r) and r["n"] == 30 and r["unit"] == "us"
    assert r["min"] <= r["median"] <= r["p90"] <= r["p99"] <= r["max"]
    assert r["x_floor_median"] > 1  # a Python client over TCP costs more than the C floor
    assert "C floor, same CPU" in {x["name"] for x in results}
    paper = by_name(results, "paper Table 5: JOINT_TRAJ_PT -> reply")
    assert paper["reference"] and paper["mean"] == pytest.approx(33_900)


def test_paper_model_gives_its_latency_floor() -> None:
    code, results, err = bench("rtt", "--count", "10", "--floor-n", "10", "--paper-model")
    assert code == 0, err
    r = by_name(results, "JOINT_TRAJ_PT -> reply")
    assert r["min"] >= 20_000  # the model's 20 ms latency, plus its gamma-distributed jitter
    assert r["std"] > 0


def test_jitter_json_is_the_state_period() -> None:
    code, results, err = bench("jitter", "--count", "15")
    assert code == 0, err
    r = by_name(results, "state period")
    assert TABLE5 <= set(r) and r["n"] == 15
    assert 5_000 < r["median"] < 100_000  # the bench simulator publishes every 20 ms


def _sim_on_adjacent_ports(**kw: Any) -> tuple[AbbSim, int]:
    """A simulator whose state port is its motion port + 2 (what ``--url`` assumes)."""
    for _ in range(50):
        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            port = probe.getsockname()[1]
        if port > 65000:
            continue
        sim = AbbSim(state_ms=10.0, **kw)
        try:
            sim.serve_tcp("127.0.0.1", port, port + 2)
            return sim, port
        except OSError:
            sim.close()
    pytest.skip("no two free ports two apart")


def test_url_runs_against_that_controller() -> None:
    sim, port = _sim_on_adjacent_ports()
    with sim:
        code, results, err = bench("rtt", "--count", "12", "--floor-n", "10",
                                   f"tcp://127.0.0.1:{port}")  # fmt: skip
        assert code == 0, err
        assert f"127.0.0.1:{port}" in by_name(results, "JOINT_TRAJ_PT -> reply")["where"]
        state = sim.snapshot()
    assert state.points_received >= 12 + 5 and state.trajectories == 0  # nothing activated
    assert state.dropped_points == 0  # each -1 restarts the download: the buffer never fills


@pytest.mark.parametrize("profile", ["abb", "generic"])
def test_library_round_trips_never_move_the_arm(make_sim: Any, make_arm: Any,
                                                profile: str) -> None:  # fmt: skip
    sim, mp, sp = make_sim(profile=profile)
    arm = make_arm(mp, sp)
    before = sim.snapshot().joints
    run = rtt(arm, Run("rtt", 20))
    assert run.complete and (run.values > 0).all()
    assert sim.snapshot().joints == pytest.approx(before, abs=1e-6)
    assert sim.snapshot().rejected_points == (1 if profile == "generic" else 0)
    periods = state_periods(arm, Run("period", 5))
    assert periods.complete and (periods.values >= 0).all()


@pytest.mark.parametrize("url,expected", [
    ("192.168.125.1", ("192.168.125.1", 11000, 11002)),
    ("tcp://10.0.0.2:50240", ("10.0.0.2", 50240, 50242)),
    ("robot:12000", ("robot", 12000, 12002)),
])  # fmt: skip
def test_parse_url(url: str, expected: tuple[str, int, int]) -> None:
    assert parse_url(url) == expected


@pytest.mark.parametrize("url", ["host:x", ":11000", "host:0", "host:65535"])
def test_parse_url_refuses(url: str) -> None:
    with pytest.raises(InvalidArgument, match="HOST:MOTION_PORT"):
        parse_url(url)


def test_bad_arguments_one_line() -> None:
    done = subprocess.run([*BENCH, "rtt", "--target", "arm", "--paper-model", "x"],
                          capture_output=True, text=True, timeout=30)  # fmt: skip
    assert done.returncode == 2 and len(done.stderr.splitlines()) == 1
    assert "--paper-model" in done.stderr
    done = subprocess.run([*BENCH, "jitter", "--target", "arm", "h:x"],
                          capture_output=True, text=True, timeout=30)  # fmt: skip
    assert done.returncode == 2 and len(done.stderr.splitlines()) == 1


@pytest.mark.parametrize(
    ("kind", "target"), [("rtt", "pioneer"), ("rtt", "hub"), ("jitter", "pioneer")]
)
def test_paper_model_is_for_the_arm_only(kind: str, target: str) -> None:
    """(``bench jitter --target hub`` is refused earlier: jitter has no hub target.)"""
    done = subprocess.run([*BENCH, kind, "--target", target, "--paper-model", "-n", "10"],
                          capture_output=True, text=True, timeout=30)  # fmt: skip
    assert done.returncode == 2 and len(done.stderr.splitlines()) == 1
    assert "--paper-model" in done.stderr and target in done.stderr


def test_state_period_model_has_the_shape_of_table5() -> None:
    """The model's state period (the paper's σ, 18 ms, around 20 ms) in the shape Table 5
    reports: mean 20.3, median 15.7, σ 18.0, min 0.5, max 63.0 ms."""
    from robocli.sim.abb.server import ControllerModel

    rng = np.random.default_rng(7)
    draws = np.array([ControllerModel.paper().state_period_ms(rng, 20.0) for _ in range(20_000)])
    assert draws.mean() == pytest.approx(20.0, abs=0.5)
    assert draws.std() == pytest.approx(18.0, abs=0.8)
    assert 13.0 < np.median(draws) < 16.5  # skewed: most periods short, a few long
    assert 0.45 < draws.min() < 1.0 and 55.0 < draws.max() < 63.6
    narrow = [ControllerModel(period_jitter_ms=1.0).state_period_ms(rng, 20.0) for _ in range(500)]
    assert np.std(narrow) == pytest.approx(1.0, abs=0.2) and 15 < min(narrow) < max(narrow) < 25
    assert ControllerModel(latency_ms=5.0).state_period_ms(rng, 20.0) == 20.0


def test_state_periods_on_the_wire_follow_the_model(make_sim: Any, make_arm: Any) -> None:
    """The periods between the simulator's own stamps (JOINT_FEEDBACK's controller time),
    not between receive times: a loaded host wakes the publisher late and the client later
    still, which bends receive times, not the controller's clock. The publisher is stalled
    once for 0.4 s on purpose (as a loaded host does): the deadlines it missed are sent
    late, each at its instant, and the periods still follow the model."""
    from robocli.sim.abb.server import ControllerModel

    sim, mp, sp = make_sim(state_ms=20.0, time_scale=2.0, feedback=True,
                           model=ControllerModel(period_jitter_ms=18.0))  # fmt: skip
    arm = make_arm(mp, sp, motion=False)
    rec = arm.record()
    arm.wait_for_state()
    with sim.controller.lock:  # the publisher blocks here, as behind a busy CPU
        time.sleep(0.4)  # the stall itself (0.8 s simulated), not a wait for something
    deadline = time.monotonic() + 30
    while sum(s.robot_time is not None for s in list(rec.samples)) < 160:
        assert time.monotonic() < deadline, "the states sent were not received"
        arm.wait_for_state(10)
    rec.stop()
    ms = np.diff(rec.log().time)[:150] * 1e3  # simulated ms
    assert ms.size == 150
    assert 15.0 < ms.mean() < 25.0 and ms.std() > 12.0  # the exact simulator: σ about 1 ms
    assert np.median(ms) < 0.85 * ms.mean() and ms.min() < 3.0 and ms.max() < 70.0
    assert ms.min() > 0.45  # the model's shortest period: no burst shows up in the stamps
