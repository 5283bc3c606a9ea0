"""``robocli bridge arm``: a simulated ABB arm on Zenoh, the bridge in its own process. It
streams joints, TCP pose and status; it takes one trajectory upload from the holder, refuses
one from anyone else, and stops a running trajectory when its holder's liveliness goes."""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

import pytest

from robocli.sim.abb.server import AbbSim
from robocli.zenoh import open_session
from tests.bridge.bridge_helpers import Events, acquire, bridge_process, holder_token, query
from tests.waiting import wait_for


@pytest.fixture
def arm(endpoint: str) -> Iterator[tuple[AbbSim, Any]]:
    """A simulator, a bridge ``a1`` over it, and a client session on the bridge."""
    with AbbSim("irb120", state_ms=20) as simulator:
        motion, state = simulator.serve_tcp("127.0.0.1", 0, 0)
        ports = ["--motion-port", motion.rsplit(":", 1)[1], "--state-port",
                 state.rsplit(":", 1)[1]]  # fmt: skip
        with bridge_process(["arm", "127.0.0.1", *ports, "--zenoh", endpoint, "--name", "a1"]):
            session = open_session(endpoint, "client")
            try:
                yield simulator, session
            finally:
                session.close()


def _joints(events: Events) -> list[float]:
    return list(events.items[-1]["joints"]) if events.items else []


def _take(session: Any, holder: str) -> Any:
    reply = acquire(session, "a1", holder)
    assert reply["granted"] is True and reply["holder"] == holder
    return holder_token(session, "a1", holder)


def _upload(session: Any, holder: str, q0: list[float], dq: float, seconds: float) -> Any:
    goal = [q0[0] + dq, *q0[1:]]
    payload = {"time": [0.0, seconds], "joints": [q0, goal], "first_duration": 0.2}
    return query(session, f"robocli/a1/@control/{holder}/trajectory", payload)


def test_the_arm_bridge_streams_joints_and_takes_one_upload(arm) -> None:
    simulator, session = arm
    states = Events(session, "robocli/a1/state")
    statuses = Events(session, "robocli/a1/status")
    q0 = wait_for(lambda: _joints(states), "joint samples on robocli/a1/state")
    sample = states.items[-1]
    assert len(sample["joints"]) == 6 and len(sample["tcp"]["position"]) == 3
    wait_for(lambda: statuses.items, "a status on robocli/a1/status")
    assert statuses.items[-1]["in_motion"] in (False, None)
    info = query(session, "robocli/a1/@info")
    assert info["kind"] == "arm" and info["model"] == "irb120"

    # anyone but the holder is refused, before anything reaches the arm
    refused = _upload(session, "mallory", q0, 0.2, 1.0)
    assert "does not hold" in refused["error"]
    token = _take(session, "grace")
    try:
        assert _upload(session, "grace", q0, 0.2, 1.0) == {"points": 2}
        wait_for(lambda: abs(_joints(states)[0] - (q0[0] + 0.2)) < 1e-3, "the arm at its goal")
        assert simulator.snapshot().trajectories == 1
        bad = _upload(session, "grace", q0, 50.0, 1.0)  # far beyond joint 1's range
        assert "error" in bad and simulator.snapshot().trajectories == 1
    finally:
        token.undeclare()


def test_a_running_trajectory_stops_when_its_holder_goes(arm) -> None:
    simulator, session = arm
    states = Events(session, "robocli/a1/state")
    events = Events(session, "robocli/a1/@control/event")
    q0 = wait_for(lambda: _joints(states), "joint samples")
    token = _take(session, "heidi")
    assert _upload(session, "heidi", q0, 0.5, 20.0) == {"points": 2}
    wait_for(lambda: simulator.snapshot().in_motion, "the arm moves")
    token.undeclare()
    wait_for(lambda: simulator.snapshot().stops >= 1, "STOP (-4) reaches the arm")
    gone = wait_for(lambda: events.find(event="released"), "a release event")
    assert gone["holder"] == "heidi"
    assert json.loads(json.dumps(query(session, "robocli/a1/@control"))) == {"holder": None}


def test_an_upload_that_does_not_decode_gets_an_error_reply(arm) -> None:
    _, session = arm
    token = _take(session, "ivy")
    try:
        for bad in (b"[" * 100_000, b'{"time":[0,1e400],"joints":[[0,0,0,0,0,0],[0,0,0,0,0,0]]}',
                    b'{"time":[0,1' + b"0" * 400 + b'],"joints":[]}'):  # fmt: skip
            replies = list(session.get("robocli/a1/@control/ivy/trajectory", payload=bad,
                                       timeout=20.0))  # fmt: skip
            assert len(replies) == 1 and replies[0].err is not None, bad[:20]
            assert "error" in json.loads(replies[0].err.payload.to_bytes())
    finally:
        token.undeclare()
