"""The one periodic loop's policy (``robocli.serving.periodic``): a step that raises is
logged once per run of failures with its traceback, counted and handed to the owner, and the
loop goes on unless the owner stops it; a step that overruns its period is not caught up in a
burst. And the loops built on it keep the policy: the arm simulator's state stream outlives
a state that fails to build, a session's task ends on its first error."""

from __future__ import annotations

import logging
import socket
import threading
from collections.abc import Iterator

import pytest

from robocli.devices.tasks import PeriodicTask
from robocli.serving.periodic import PeriodicLoop
from robocli.sim.abb.server import AbbSim
from tests.waiting import wait_for

LOGGER = "robocli.serving.periodic"
JOIN_S = 10.0


@pytest.fixture
def loops() -> Iterator[list[PeriodicLoop]]:
    made: list[PeriodicLoop] = []
    yield made
    for loop in made:
        loop.close()


def _records(caplog: pytest.LogCaptureFixture, level: int, name: str) -> list[logging.LogRecord]:
    return [
        r
        for r in caplog.records
        if r.name == LOGGER and r.levelno == level and r.getMessage().startswith(name)
    ]


def test_a_step_that_raises_is_logged_once_counted_and_the_loop_goes_on(
    loops: list[PeriodicLoop], caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.DEBUG, LOGGER)
    calls = [0]

    def step() -> None:
        calls[0] += 1
        if calls[0] <= 3:
            raise ValueError(f"bad tick {calls[0]}")

    loop = PeriodicLoop("flaky", step, period=0.005)
    loops.append(loop)
    loop.start()
    wait_for(lambda: loop.runs >= 6, "the loop went on after its failures")
    assert loop.errors == 3
    errors = _records(caplog, logging.ERROR, "flaky")
    assert len(errors) == 1 and errors[0].exc_info is not None  # once, with its traceback
    assert "bad tick 1" in caplog.text
    assert len(_records(caplog, logging.DEBUG, "flaky: step failed")) == 2
    assert [r.getMessage() for r in _records(caplog, logging.INFO, "flaky")] == [
        "flaky: the step works again after 3 failures"
    ]


def test_every_error_goes_to_the_owner_and_an_owner_that_stops_ends_the_loop(
    loops: list[PeriodicLoop],
) -> None:
    told: list[BaseException] = []
    calls = [0]

    def step() -> float:
        calls[0] += 1
        raise OSError("link lost")

    def on_error(exc: BaseException) -> None:
        told.append(exc)
        if len(told) == 2:
            loop.stop()

    loop = PeriodicLoop("heartbeat", step, on_error=on_error)
    loops.append(loop)
    loop.start()
    loop.thread.join(JOIN_S)
    assert not loop.thread.is_alive()
    assert calls[0] == 2 and loop.errors == 2
    assert [str(e) for e in told] == ["link lost", "link lost"]


def test_an_owner_that_cannot_be_told_ends_the_loop(
    loops: list[PeriodicLoop], caplog: pytest.LogCaptureFixture
) -> None:
    def step() -> float:
        raise ValueError("bad step")

    def on_error(exc: BaseException) -> None:
        raise RuntimeError("owner gone")

    loop = PeriodicLoop("orphan", step, on_error=on_error)
    loops.append(loop)
    loop.start()
    loop.thread.join(JOIN_S)
    assert not loop.thread.is_alive() and loop.runs == 1
    said = [r.getMessage() for r in _records(caplog, logging.ERROR, "orphan")]
    assert len(said) == 2 and "could not be told" in said[1]


def test_an_exit_ends_the_loop_after_being_logged(
    loops: list[PeriodicLoop], caplog: pytest.LogCaptureFixture
) -> None:
    def step() -> float:
        raise SystemExit(3)

    loop = PeriodicLoop("exiting", step)
    loops.append(loop)
    loop.start()
    loop.thread.join(JOIN_S)
    assert not loop.thread.is_alive() and loop.runs == 1 and loop.errors == 1
    assert len(_records(caplog, logging.ERROR, "exiting")) == 1


def test_a_step_that_overruns_its_period_skips_the_deadlines_it_missed(
    loops: list[PeriodicLoop], caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.DEBUG, LOGGER)
    period = 0.02
    held = threading.Event()  # never set: the first step holds the loop 5.5 periods

    def step() -> None:
        if loop.runs == 0:
            held.wait(5.5 * period)

    loop = PeriodicLoop("slow", step, period=period)
    loops.append(loop)
    loop.start()
    wait_for(lambda: loop.runs >= 3, "the loop ran on after its slow step")
    # the step started at its deadline t0 + period or later and ended 5.5 periods on: the
    # deadlines t0 + 2..5 periods had passed, and none was run in a burst to catch up
    assert loop.skipped >= 4
    assert loop.errors == 0
    warned = _records(caplog, logging.WARNING, "slow")
    assert len(warned) == 1 and "overran" in warned[0].getMessage()


def test_a_session_task_ends_on_its_first_error_and_fails_its_session() -> None:
    failed: list[BaseException] = []
    calls = [0]

    def step() -> float:
        calls[0] += 1
        raise OSError("keep-alive write failed")

    task = PeriodicTask("robot-keepalive", step, failed.append)
    task.start()
    task.thread.join(JOIN_S)
    assert not task.thread.is_alive() and task.stopped
    assert calls[0] == 1 and [str(e) for e in failed] == ["keep-alive write failed"]


def test_the_arm_simulators_state_stream_outlives_a_state_that_fails_to_build(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    with AbbSim(state_ms=5.0) as sim:
        _, state_url = sim.serve_tcp(motion_port=0, state_port=0)
        host, port = state_url.removeprefix("tcp://").rsplit(":", 1)
        real = sim.controller.state_messages
        broken = threading.Event()

        def once_broken(t: float, feedback: bool) -> bytes:
            if not broken.is_set():
                broken.set()
                raise ValueError("a state that cannot be built")
            return real(t, feedback)

        with socket.create_connection((host, int(port)), timeout=10.0) as client:
            sim.wait_until(lambda s: s.state_clients == 1, 10.0)
            monkeypatch.setattr(sim.controller, "state_messages", once_broken)
            wait_for(broken.is_set, "the stream tried to build a state")
            sent = sim.states_sent
            sim.wait_until(lambda s: s.states_sent > sent + 3, 10.0)  # the stream went on
            assert client.recv(4096)
        assert sim._publisher is not None and sim._publisher.errors == 1
