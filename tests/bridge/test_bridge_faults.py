"""Faults of a bridge: a stop (or a stop rule) that raises never ends the thread that applies
the stop rules; a bridge that stalled past the robot's watchdog reports a fault and never
resumes motion."""

from __future__ import annotations

import json
import os
import signal
from collections.abc import Iterator
from typing import Any

import pytest

from robocli.bridge import RemotePioneer
from robocli.bridge.control import ControlGate
from robocli.sim.pioneer.server import PioneerSim
from robocli.zenoh import open_session
from tests.bridge.bridge_helpers import Events, bridge_process
from tests.waiting import wait_for


@pytest.fixture
def server(endpoint: str) -> Iterator[Any]:
    session = open_session(endpoint, "server")
    try:
        yield session
    finally:
        session.close()


def test_a_stop_that_raises_never_ends_the_gates_thread(server, endpoint) -> None:
    calls: list[str] = []

    def stop(reason: str) -> None:
        calls.append(reason)
        if len(calls) == 1:
            raise RuntimeError("the robot's link broke")

    gate = ControlGate(server, "g1", stop=stop, silence=0.2)
    client = open_session(endpoint, "client")
    try:
        events = Events(client, "robocli/g1/@control/event")
        wait_for(lambda: _acquire(client, "ivan"), "the grant")
        token = client.liveliness().declare_token("robocli/g1/@control/ivan/alive")
        for expected in (1, 2):  # the first stop raises; the thread still applies the second
            with gate.command("ivan", moving=True, epoch=gate.epoch) as ok:
                assert ok
            wait_for(lambda n=expected: len(calls) >= n, f"stop {expected}")
        assert gate.counts["stop_errors"] == 1 and gate.counts["stops"] == 1
        fault = wait_for(lambda: events.find(event="fault"), "the fault event")
        assert "link broke" in fault["reason"]
        assert gate.holder == "ivan"  # a silence stop keeps the holder
        with gate.command("mallory", moving=True) as ok:
            assert not ok
        token.undeclare()
        wait_for(lambda: gate.holder is None, "the holder's token went")
    finally:
        gate.close()
        client.close()
    assert calls[-1] == "the bridge ended"


def test_a_stop_rule_that_raises_never_ends_the_gates_thread(server, endpoint, monkeypatch) -> None:
    """Whatever fails in the gate's thread (here its rules, once), the rules go on: the
    silence rule still stops a robot whose controller went quiet."""
    calls: list[str] = []
    gate = ControlGate(server, "g1", stop=calls.append, silence=0.2)
    rules, broken = gate._due, []

    def due_once_broken(now: float) -> Any:
        if not broken:
            broken.append(now)
            raise ValueError("a rule that failed")
        return rules(now)

    monkeypatch.setattr(gate, "_due", due_once_broken)
    client = open_session(endpoint, "client")
    try:
        wait_for(lambda: _acquire(client, "ivan"), "the grant")
        token = client.liveliness().declare_token("robocli/g1/@control/ivan/alive")
        with gate.command("ivan", moving=True, epoch=gate.epoch) as ok:
            assert ok
        wait_for(lambda: calls, "the silence stop, after the rule that failed")
        assert broken and calls[0].startswith("no command from ivan")
        token.undeclare()
    finally:
        gate.close()
        client.close()


def _acquire(session: Any, holder: str) -> bool:
    body = json.dumps({"op": "acquire"}).encode()
    for reply in session.get(f"robocli/g1/@control/{holder}/request", payload=body, timeout=5.0):
        return bool(reply.ok is not None and json.loads(reply.ok.payload.to_bytes())["granted"])
    return False


def test_a_bridge_stalled_past_the_watchdog_reports_a_fault_and_never_resumes(endpoint) -> None:
    """SIGSTOP the bridge while a controller drives: the robot's watchdog stops it. On
    SIGCONT the bridge reports a fault, ignores motion until the holder sends a stop, and
    the controller does not re-send its stale set-point."""
    with PioneerSim(watchdog_s=1.0) as simulator:
        url = simulator.serve_tcp("127.0.0.1", 0)
        with bridge_process(["pioneer", url, "--zenoh", endpoint, "--name", "r1",
                             "--silence", "60"]) as (bridge, _):  # fmt: skip
            with RemotePioneer.connect("r1", endpoint, holder="judy") as driver:
                events = Events(driver._session, "robocli/r1/@control/event")
                driver.set_velocity(0.3)
                wait_for(lambda: simulator.snapshot().trans_vel_set > 0.1, "the robot moves")
                os.kill(bridge.pid, signal.SIGSTOP)
                try:
                    wait_for(lambda: simulator.snapshot().watchdog_trips >= 1,
                             "the robot's watchdog stops it")  # fmt: skip
                    # 3 SIP cycles more: the bridge's silence is then well past the watchdog
                    sips = simulator.snapshot().sips_sent
                    wait_for(lambda: simulator.snapshot().sips_sent >= sips + 3, "3 SIP cycles")
                finally:
                    os.kill(bridge.pid, signal.SIGCONT)
                fault = wait_for(lambda: events.find(event="fault"), "a fault event")
                assert fault["holder"] == "judy" and "watchdog" in fault["reason"]
                wait_for(lambda: driver.fault is not None, "the controller hears of it")
                # the holder's stale set-point, sent again by hand, is ignored
                driver._send((0.3, 0.0, driver._epoch))
                seen = driver.wait_for_state().sip_count
                wait_for(lambda: driver.wait_for_state().sip_count >= seen + 5, "5 more SIPs")
                assert simulator.snapshot().trans_vel_set == 0
                driver.stop()  # the holder stops: motion may resume on its next command
                driver.set_velocity(0.2)
                wait_for(lambda: simulator.snapshot().trans_vel_set > 0.1, "moving again")
