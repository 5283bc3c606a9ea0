"""A stall of the client's own write, placed where a stale set-point could slip through:
after its bytes left (between the write and the stamp of its time), and before they left
(between the silence check and the write). Held until the simulator's watchdog stopped the
robot, then released: the stale set-point never reaches the robot again, the trip is
reported, and only a fresh command moves it. Deterministic: the stall is an event, not
SIGSTOP timing."""

from __future__ import annotations

import threading
from collections.abc import Iterator

import pytest

from robocli.devices.pioneer import Pioneer, WatchdogTrip, WatchdogTripped
from robocli.sim.pioneer.server import PioneerSim
from robocli.sim.world import World
from robocli.transports import open_transport
from tests.stalling import WAIT, MotionProbe, StallingTransport
from tests.waiting import wait_for


@pytest.fixture
def sim() -> Iterator[PioneerSim]:
    with PioneerSim("p3dx", time_scale=2.0, world=World.empty(), watchdog_s=1.0) as simulator:
        simulator.serve_tcp("127.0.0.1", 0)
        yield simulator


@pytest.mark.parametrize("where", ["after", "before"])
def test_a_write_stalled_past_the_watchdog_never_resends_the_stale_set_point(
    sim: PioneerSim, where: str
) -> None:
    assert sim.url is not None
    link = StallingTransport(open_transport(sim.url), where)
    trips: list[WatchdogTrip] = []
    tripped = threading.Event()
    with Pioneer.from_transport(link, keepalive=0.2, sip_timeout=120) as robot:
        assert robot.watchdog == 1.0  # the simulator's, from its CONFIG
        robot.add_listener(lambda trip: (trips.append(trip), tripped.set()), kind="watchdog")
        robot.enable_motors()
        robot.set_velocity(0.0, 0.5)
        sim.wait_until(lambda s: s.rot_vel > 0.2, WAIT)
        probe = MotionProbe(sim)
        link.arm()  # the keep-alive's next re-send of the set-point stalls
        assert link.stalled.wait(WAIT)
        sim.wait_until(lambda s: s.watchdog_trips >= 1 and s.rot_vel == 0.0, WAIT)
        pulses = sim.snapshot().commands["PULSE"]
        link.release.set()

        assert tripped.wait(WAIT), "the stall was not reported"
        # the keep-alive goes on (PULSEs): never with the stale set-point
        sim.wait_until(lambda s: s.commands["PULSE"] >= pulses + 3, WAIT)
        assert probe.moving_after_trip() == [], "the stale set-point reached the robot"
        s = sim.snapshot()
        assert s.rot_vel_set == 0.0 and s.rot_vel == 0.0
        assert len(trips) == 1 and trips[0].silence > 1.0 and robot.stats.watchdog_trips == 1

        with pytest.raises(WatchdogTripped, match="not sent"):
            robot.set_velocity(0.0, 0.5)  # the first command after the trip says so
        assert sim.snapshot().rot_vel_set == 0.0
        robot.set_velocity(0.0, 0.4)  # a fresh command moves the robot again
        sim.wait_until(lambda s: s.rot_vel_set > 0.3, WAIT)


def test_close_never_waits_for_a_write_stalled_forever(sim: PioneerSim) -> None:
    """A writer stalled inside the transport holds the write lock; close() (and the stop it
    sends) waits for it no longer than its own deadline, then shuts the transport down,
    which wakes the writer: an earlier design hung here."""
    assert sim.url is not None
    link = StallingTransport(open_transport(sim.url), "after")
    robot = Pioneer.from_transport(link, keepalive=0.2, sip_timeout=120)
    robot.enable_motors()
    robot.set_velocity(0.0, 0.5)
    link.arm()
    assert link.stalled.wait(WAIT)
    closer = threading.Thread(target=robot.close, daemon=True)
    closer.start()
    closer.join(WAIT)
    assert not closer.is_alive(), "close() hung on the stalled writer"
    assert robot._session.stuck_threads == []
    sim.wait_until(lambda s: not s.session_open or s.clients == 0, WAIT)


def test_a_re_send_waiting_behind_a_stalled_write_is_dropped_after_the_trip(
    sim: PioneerSim,
) -> None:
    """The program's own write stalls after its bytes left; meanwhile the keep-alive has
    read the set-points and waits for the link. Once the stall is found (the trip), what the
    keep-alive decided before it is stale: it never reaches the robot."""
    assert sim.url is not None
    link = StallingTransport(open_transport(sim.url), "after")
    link.write_timeout = WAIT  # writers wait behind the stall, not fail the session
    trips: list[WatchdogTrip] = []
    with Pioneer.from_transport(link, keepalive=0.2, sip_timeout=120) as robot:
        robot.add_listener(trips.append, kind="watchdog")
        robot.enable_motors()
        robot.set_velocity(0.0, 0.5)
        sim.wait_until(lambda s: s.rot_vel > 0.2, WAIT)
        probe = MotionProbe(sim)
        link.arm()
        program = threading.Thread(target=robot.set_velocity, args=(0.0, 0.5), daemon=True)
        program.start()  # its write stalls after the bytes left
        assert link.stalled.wait(WAIT)
        keepalives = robot.stats.keepalives
        # the keep-alive has read the set-points and waits for the link
        wait_for(lambda: robot.stats.keepalives != keepalives,
                 "the keep-alive trying again", timeout=WAIT)  # fmt: skip
        sim.wait_until(lambda s: s.watchdog_trips >= 1 and s.rot_vel == 0.0, WAIT)
        pulses = sim.snapshot().commands["PULSE"]
        link.release.set()
        program.join(WAIT)
        sim.wait_until(lambda s: s.commands["PULSE"] >= pulses + 3, WAIT)
        assert probe.moving_after_trip() == [], "a stale set-point reached the robot"
        assert sim.snapshot().rot_vel_set == 0.0
        assert len(trips) == 1
