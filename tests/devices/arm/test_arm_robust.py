"""The Arm client's guarantees: listeners that raise are isolated, history and recordings are
bounded, every wait has a timeout, close is bounded, bad options are refused."""

from __future__ import annotations

import time
from typing import Any

import pytest

from robocli.devices.arm import Arm
from robocli.errors import InvalidArgument, TimeoutError
from robocli.kinematics import load_model
from robocli.kinematics.trajectory import circle
from tests.waiting import wait_for

IRB = load_model("irb120")


def test_raising_listeners_do_not_stop_the_state_stream(make_sim, make_arm) -> None:
    sim, mp, sp = make_sim(state_ms=5.0)
    arm = make_arm(mp, sp, motion=False)

    def bad_frame(direction: str, frame: bytes, t: float) -> None:
        raise RuntimeError("printing listener whose pipe closed")

    def bad_sample(sample: object) -> None:
        raise ValueError("broken consumer")

    arm.add_listener(bad_frame)
    arm.add_listener(bad_sample, kind="samples")
    first = arm.wait_for_state()
    for _ in range(20):
        last = arm.wait_for_state()
    assert last.t > first.t
    assert arm.stats["state"]["listener_errors"] >= 40


def test_history_and_recording_are_bounded(make_sim, make_arm) -> None:
    """On the controller's clock (JOINT_FEEDBACK), every sample kept makes the log: on
    receive times, a loaded machine reads the last 30 in one go, and one read is one time."""
    sim, mp, sp = make_sim(state_ms=5.0, time_scale=2.0, feedback=True)
    arm = make_arm(mp, sp, motion=False, history=50)
    received: list[object] = []
    arm.add_listener(received.append, kind="samples")
    rec = arm.record(max_samples=30)
    deadline = time.monotonic() + 30
    while len(received) < 200:  # 4 x the history, about 0.25 s
        assert time.monotonic() < deadline, len(received)
        arm.wait_for_state()
    rec.stop()
    assert len(arm.history) == 50 and len(rec.samples) == 30
    timed = [s for s in rec.samples if s.robot_time is not None]
    assert len(rec.log()) == len(timed) and 10 <= len(timed) <= 20  # every other one


def test_motion_reply_timeout_and_bounded_close(talking_server) -> None:
    silent = talking_server(b"")  # accepts, never answers
    arm = Arm.connect("127.0.0.1", silent.port, state=False, timeout=60.0)
    start = time.monotonic()
    with pytest.raises(TimeoutError, match="no reply to point -1"):
        arm.download(circle(IRB, 10, duration=1.0), timeout=0.3)
    assert time.monotonic() - start < 30.0  # the call's 0.3 s, not the link's 60 s
    start = time.monotonic()
    arm.close()  # sends STOP (the download may have activated nothing, but may run)
    assert time.monotonic() - start < 10.0  # bounded (close_timeout, 2 s), not hanging


def test_state_port_silence_times_out(talking_server) -> None:
    silent = talking_server(b"")
    with pytest.raises(TimeoutError, match="no state message"):
        Arm.connect("127.0.0.1", state_port=silent.port, motion=False, timeout=0.3)


@pytest.mark.parametrize("kw", [{"byte_order": "middle"}, {"real_size": 2},
                                {"motion": False, "state": False}])  # fmt: skip
def test_bad_options(kw) -> None:
    with pytest.raises(InvalidArgument):
        Arm.connect("127.0.0.1", **kw)


def test_state_only_arm_refuses_motion(make_sim, make_arm) -> None:
    sim, mp, sp = make_sim()
    arm = make_arm(mp, sp, motion=False)
    with pytest.raises(InvalidArgument, match="motion port"):
        arm.stop()
    assert sim.snapshot().points_received == 0


def test_controller_gone_fails_closed(make_sim, make_arm) -> None:
    """The controller disappears mid-motion: the next call raises ConnectionLost, close()
    still finishes within its bound."""
    from robocli.errors import ConnectionLost

    sim, mp, sp = make_sim()
    arm = make_arm(mp, sp)
    arm.download(circle(IRB, 20, duration=8.0), first_duration=1.0)
    sim.close()
    with pytest.raises(ConnectionLost):
        for _ in range(100):
            arm.wait_for_state(10)
    start = time.monotonic()
    arm.close()
    assert time.monotonic() - start < 10.0  # bounded (close_timeout, 2 s), not hanging


@pytest.mark.slow
def test_recording_memory_stays_bounded(make_sim, make_arm) -> None:
    """Thousands of states through a bounded history and recording: memory stays flat."""
    import tracemalloc

    sim, mp, sp = make_sim(state_ms=2.0, time_scale=2.0, feedback=True)
    arm = make_arm(mp, sp, motion=False, history=500)
    rec = arm.record(max_samples=500)

    def states(n: int) -> None:
        before = sim.snapshot().states_sent
        while sim.snapshot().states_sent < before + n:
            arm.wait_for_state()

    tracemalloc.start()  # tracks what is allocated from now on: turn both buffers over first
    try:
        states(400)
        base = _client_bytes(tracemalloc.take_snapshot())
        states(2500)
        grown = _client_bytes(tracemalloc.take_snapshot()) - base
    finally:
        tracemalloc.stop()
    rec.stop()
    assert len(arm.history) == 500 and len(rec.samples) == 500
    # unbounded, 5000 more samples would take ~0.9 MB here; CPython's tuple free lists keep
    # up to ~180 kB of freed joint tuples counted
    assert grown < 400_000, f"{grown} bytes more after 2500 more states"


def _client_bytes(snapshot: Any) -> int:
    """Bytes allocated by the client's code (the simulator in this process is left out)."""
    import tracemalloc

    mine = snapshot.filter_traces([tracemalloc.Filter(True, "*robocli/devices/*")])
    return sum(stat.size for stat in mine.statistics("filename"))


@pytest.mark.parametrize("ports", [{"state": False}, {"motion": False}, {}])
def test_alive_and_check_follow_each_link(make_sim, make_arm, ports) -> None:
    """``alive`` turns False and ``check()`` raises the link's error once the controller
    drops the connection (the motion port alone is quiet: nothing else would notice)."""
    from robocli.errors import ConnectionLost

    sim, mp, sp = make_sim()
    arm = make_arm(mp, sp, **ports)
    assert arm.alive
    arm.check()  # returns
    sim.close()
    wait_for(lambda: not arm.alive, "the arm to see the link lost")
    assert not arm.alive
    with pytest.raises(ConnectionLost):
        arm.check()


def test_a_closed_arm_is_not_alive(make_sim, make_arm) -> None:
    from robocli.errors import ConnectionLost

    _, mp, sp = make_sim()
    arm = make_arm(mp, sp)
    arm.close()
    assert not arm.alive
    with pytest.raises(ConnectionLost, match="closed"):
        arm.check()
