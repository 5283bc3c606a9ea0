"""Motion only on a fresh command, through a bridge. A controller whose sending thread
stalls while its set-point is on the way (what SIGSTOP did: the re-send went out after the
bridge's silence stop, before the controller handled the stop event) never turns the robot
again; and a bridge whose own write to the robot stalls past the robot's watchdog never
re-sends the stale set-point. The stalls are events, so each run tests the same order."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from typing import Any

import pytest

from robocli.bridge import RemotePioneer
from robocli.bridge.control import ControlGate
from robocli.bridge.pioneer import PioneerBridge
from robocli.devices.pioneer import Pioneer
from robocli.sim.pioneer.server import PioneerSim
from robocli.sim.world import World
from robocli.transports import open_transport
from robocli.zenoh import open_session
from tests.bridge.bridge_helpers import Events, query
from tests.simulators import pioneer_on_loopback
from tests.stalling import WAIT, MotionProbe, StallingTransport
from tests.waiting import wait_for


class StallingController(RemotePioneer):
    """A RemotePioneer whose re-sending thread, once :attr:`armed`, stalls inside its next
    put (the set-point read, not yet sent) until :attr:`release`; while :attr:`hold_events`
    is set, the bridge's events wait for :meth:`flush_events` (a process stopped handles
    them only after its stale re-send). :attr:`sent` is every set-point put."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.armed, self.stalled = threading.Event(), threading.Event()
        self.release, self.hold_events = threading.Event(), threading.Event()
        self.kept: list[Any] = []
        self.sent: list[tuple[float, float, int | None]] = []
        super().__init__(*args, **kwargs)

    def _send(self, point: tuple[float, float, int | None]) -> None:
        if self.armed.is_set() and threading.current_thread() is self._resender.thread:
            self.armed.clear()
            self.stalled.set()
            assert self.release.wait(WAIT), "the stalled re-send was never released"
        self.sent.append(point)
        super()._send(point)

    def _on_event(self, sample: Any) -> None:
        if self.hold_events.is_set():
            self.kept.append(sample)
            return
        super()._on_event(sample)

    def flush_events(self) -> None:
        self.hold_events.clear()
        kept, self.kept = self.kept, []
        for sample in kept:
            super()._on_event(sample)


@pytest.fixture
def sim() -> Iterator[PioneerSim]:
    with pioneer_on_loopback(time_scale=2.0, world=World.empty(), watchdog_s=1.0) as simulator:
        yield simulator


def _handled(bridge: PioneerBridge) -> int:
    """Velocity commands the bridge's gate has taken or ignored."""
    return sum(bridge.gate.counts.get(k, 0) for k in ("commands", "stale_commands",
                                                      "ignored_commands"))  # fmt: skip


def _moving(points: list[tuple[float, float, int | None]]) -> list[Any]:
    return [p for p in points if p[:2] != (0.0, 0.0)]


def test_a_stalled_controller_never_turns_the_robot_again_with_its_stale_set_point(
    sim: PioneerSim, endpoint: str
) -> None:
    assert sim.url is not None
    server = open_session(endpoint, "server")
    robot = Pioneer.connect(sim.url, sip_timeout=120)
    bridge = PioneerBridge(robot, server, "r1", silence=0.3)
    try:
        with StallingController.connect("r1", endpoint, holder="kim") as driver:
            driver.set_velocity(0.0, 0.5)
            sim.wait_until(lambda s: s.rot_vel_set > 0.4, WAIT)
            probe = MotionProbe(sim)
            driver.hold_events.set()
            driver.armed.set()
            assert driver.stalled.wait(WAIT)
            wait_for(lambda: bridge.gate.counts["stops"] >= 1, "the bridge's silence stop")
            sim.wait_until(lambda s: s.rot_vel_set == 0.0, WAIT)
            stopped, handled = len(probe.taken), _handled(bridge)

            driver.release.set()  # the stale re-send goes out, the stop event not yet handled
            wait_for(lambda: _handled(bridge) > handled, "the bridge takes the stale set-point")
            with bridge.gate._robot_lock:  # (a command taken reaches the robot under it)
                assert [t for t in probe.taken[stopped:] if t.arg] == [], "the robot turned again"
            assert bridge.gate.counts["stale_commands"] >= 1
            assert sim.snapshot().rot_vel_set == 0.0

            driver.flush_events()  # now the controller hears of the stop
            assert driver.fault is not None
            sent = len(driver.sent)
            seen = driver.wait_for_state().sip_count
            wait_for(lambda: driver.wait_for_state().sip_count >= seen + 10, "10 more SIPs")
            assert _moving(driver.sent[sent:]) == [], "the controller re-sent a stale set-point"
            assert [t for t in probe.taken[stopped:] if t.arg] == []

            driver.set_velocity(0.0, 0.4)  # a fresh command moves the robot again
            sim.wait_until(lambda s: s.rot_vel_set > 0.3, WAIT)
    finally:
        bridge.close()
        robot.close()
        server.close()


@pytest.mark.parametrize("where", ["after", "before"])
def test_a_bridge_whose_write_stalls_past_the_watchdog_never_resends_the_set_point(
    sim: PioneerSim, endpoint: str, where: str
) -> None:
    assert sim.url is not None
    server = open_session(endpoint, "server")
    link = StallingTransport(open_transport(sim.url), where)
    robot = Pioneer.from_transport(link, keepalive=0.2, sip_timeout=120)
    bridge = PioneerBridge(robot, server, "r1", silence=None)
    try:
        # re-sends far apart: nothing from the controller reaches the bridge during the stall
        with RemotePioneer.connect("r1", endpoint, holder="lee", resend=600.0) as driver:
            events = Events(driver._session, "robocli/r1/@control/event")
            driver.set_velocity(0.0, 0.5)
            sim.wait_until(lambda s: s.rot_vel > 0.2, WAIT)
            probe = MotionProbe(sim)
            link.arm()  # the bridge's keep-alive re-sends the set-point: that write stalls
            assert link.stalled.wait(WAIT)
            sim.wait_until(lambda s: s.watchdog_trips >= 1 and s.rot_vel == 0.0, WAIT)
            pulses = sim.snapshot().commands["PULSE"]
            link.release.set()

            fault = wait_for(lambda: events.find(event="fault"), "the fault event")
            assert fault["holder"] == "lee" and "watchdog" in fault["reason"]
            sim.wait_until(lambda s: s.commands["PULSE"] >= pulses + 3, WAIT)
            assert probe.moving_after_trip() == [], "the stale set-point reached the robot"
            assert sim.snapshot().rot_vel_set == 0.0

            wait_for(lambda: driver.fault is not None, "the controller hears of it")
            driver.set_velocity(0.0, 0.4)  # a fresh command (a stop goes first) moves it
            sim.wait_until(lambda s: s.rot_vel_set > 0.3, WAIT)
    finally:
        bridge.close()
        robot.close()
        server.close()


def test_the_gate_refuses_moving_commands_older_than_its_last_stop(endpoint: str) -> None:
    """With an epoch: only the current one moves the robot (a stop always goes). Without
    one (a third-party controller): only after its holder's own stop since the gate's."""
    server = open_session(endpoint, "server")
    client = open_session(endpoint, "client")
    gate = ControlGate(server, "g2", stop=lambda reason: None, silence=None, token_wait=600)
    try:
        reply = query(client, "robocli/g2/@control/max/request", {"op": "acquire"})
        epoch = reply["epoch"]

        def takes(moving: bool, epoch: int | None = None) -> bool:
            with gate.command("max", moving, epoch) as ok:
                return ok

        assert takes(True) and takes(True, epoch)  # a grant starts from a stop
        gate.fault("a stall")
        assert gate.epoch == epoch + 1
        assert not takes(True) and not takes(True, epoch)  # from before the fault
        assert takes(False, epoch)  # a stop is never stale
        assert takes(True, epoch + 1)
        assert takes(True)  # its stop came after the fault
        assert gate.counts["stale_commands"] == 2
    finally:
        gate.close()
        client.close()
        server.close()
