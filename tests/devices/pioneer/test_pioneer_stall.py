"""A program that stalls past the robot's watchdog (SIGSTOP, a debugger, a GC pause, a
suspended laptop) must not drive off again with its stale set-points when it resumes: the
trip is reported (an event, and an error on the next motion command), and only a fresh
command moves the robot. Tested for real: a child process drives the built-in simulator and
is stopped with SIGSTOP until the simulator's watchdog has stopped the robot."""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator

import pytest

from robocli.sim.pioneer.server import PioneerSim, SimState
from robocli.sim.world import World
from tests.simulators import pioneer_on_loopback
from tests.waiting import wait_for

pytestmark = pytest.mark.skipif(not hasattr(signal, "SIGSTOP"), reason="POSIX signals")

WAIT = 30.0  #: bounds a failure only; every wait below ends on an event

#: The child: drives at 0.3 m/s, reports trips (after a listener that raises), then answers
#: each line on stdin with one set_velocity(0.3): "OK" or "ERROR <message>".
CHILD = r"""
import sys
from robocli.devices.pioneer import Pioneer, WatchdogTripped

def say(*words):
    print(*words, flush=True)

def broken(trip):
    raise RuntimeError("a listener that raises")

with Pioneer.connect(sys.argv[1], sip_timeout=120) as robot:
    robot.add_listener(broken, kind="watchdog")
    robot.add_listener(
        lambda trip: say("TRIP", f"{trip.silence:.3f}", f"{trip.watchdog:g}"), kind="watchdog"
    )
    robot.enable_motors()
    robot.set_velocity(0.3, 0.0)
    say("DRIVING")
    for line in sys.stdin:
        try:
            robot.set_velocity(0.3, 0.0)
        except WatchdogTripped as exc:
            say("ERROR", exc)
        else:
            say("OK")
    say("STATS", robot.stats.watchdog_trips, robot.stats.listener_errors)
"""


class Child:
    """The child process, its stdout lines read by a thread into a queue."""

    def __init__(self, url: str) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-c", CHILD, url],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        self.lines: queue.Queue[str] = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.put(line.rstrip("\n"))

    def line(self) -> str:
        try:
            return self.lines.get(timeout=WAIT)
        except queue.Empty:
            self.proc.kill()
            _, err = self.proc.communicate(timeout=WAIT)
            raise AssertionError(
                f"the child said nothing within {WAIT:g} s; stderr:\n{err}"
            ) from None

    def ask(self) -> str:
        assert self.proc.stdin is not None
        self.proc.stdin.write("\n")
        self.proc.stdin.flush()
        return self.line()


@pytest.fixture
def sim() -> Iterator[PioneerSim]:
    with pioneer_on_loopback(time_scale=2.0, world=World.empty(), watchdog_s=2.0) as simulator:
        yield simulator


def keepalives(s: SimState) -> int:
    return s.commands["PULSE"] + s.commands["VEL"] + s.commands["RVEL"]


def test_a_stalled_client_does_not_drive_off_again(sim: PioneerSim) -> None:
    assert sim.url is not None
    child = Child(sim.url)
    try:
        assert child.line() == "DRIVING"
        sim.wait_until(lambda s: s.trans_vel > 0.25, WAIT)

        os.kill(child.proc.pid, signal.SIGSTOP)  # the program stalls, mid-drive
        stopped = sim.wait_until(lambda s: s.watchdog_trips >= 1 and s.trans_vel == 0.0, WAIT)
        pulses = stopped.commands["PULSE"]
        os.kill(child.proc.pid, signal.SIGCONT)

        # the keep-alive runs again: a stop, then PULSEs; never the stale VEL 300
        def pulsing() -> SimState | None:
            s = sim.snapshot()
            assert s.trans_vel_set == 0.0 and s.trans_vel == 0.0, "the robot drove off again"
            return s if s.commands["PULSE"] >= pulses + 3 else None

        s = wait_for(pulsing, "the keep-alive after the trip", timeout=WAIT)
        assert keepalives(s) > keepalives(stopped)

        word, silence, watchdog = child.line().split()
        assert word == "TRIP" and float(silence) > 2.0 and watchdog == "2"
        answer = child.ask()  # the next motion command: refused, with the reason
        assert answer.startswith("ERROR ") and "watchdog" in answer and "not sent" in answer
        assert sim.snapshot().trans_vel_set == 0.0
        assert child.ask() == "OK"  # a fresh command moves the robot again
        sim.wait_until(lambda s: s.trans_vel_set == pytest.approx(0.3), WAIT)

        assert child.proc.stdin is not None
        child.proc.stdin.close()
        assert child.line() == "STATS 1 1"  # one trip; the raising listener was isolated
        assert child.proc.wait(WAIT) == 0
        end = sim.wait_until(lambda s: not s.session_open, WAIT)  # close() finished its stop
        assert end.trans_vel == 0.0 and not end.motors_enabled and end.commands["CLOSE"] == 1
        assert end.watchdog_trips == 1
    finally:
        if child.proc.poll() is None:
            os.kill(child.proc.pid, signal.SIGCONT)
            child.proc.kill()
        child.proc.wait(WAIT)
