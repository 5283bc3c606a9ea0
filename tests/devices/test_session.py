"""The shared client machinery, through the Pioneer client against the built-in simulator:
each test reproduces one fault that review found in the first slice."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator

import pytest

from robocli.devices.pioneer import Pioneer
from robocli.errors import ConnectionLost, TransportError
from robocli.protocols import arcos
from robocli.sim.pioneer.server import PioneerSim
from tests.waiting import run_together


class Relay:
    """A TCP relay between a client and the simulator that can stop reading the client
    (a peer that does not read) or cut the link when the client sends a given packet."""

    def __init__(self, target: str, cut_on: bytes | None = None) -> None:
        host, port = target.removeprefix("tcp://").rsplit(":", 1)
        self._target = (host, int(port))
        self.cut_on = cut_on
        self.reading = threading.Event()
        self.reading.set()
        self._srv = socket.create_server(("127.0.0.1", 0))
        self.url = f"tcp://127.0.0.1:{self._srv.getsockname()[1]}"
        self._socks: list[socket.socket] = []
        threading.Thread(target=self._run, daemon=True).start()

    def _run(self) -> None:
        client, _ = self._srv.accept()
        client.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        robot = socket.create_connection(self._target)
        self._socks = [client, robot]
        threading.Thread(target=self._pump, args=(robot, client, False), daemon=True).start()
        self._pump(client, robot, True)

    def _pump(self, src: socket.socket, dst: socket.socket, from_client: bool) -> None:
        try:
            while True:
                if from_client and not self.reading.is_set():
                    time.sleep(0.01)
                    continue
                data = src.recv(4096)
                if not data:
                    break
                if from_client and self.cut_on is not None and self.cut_on in data:
                    break
                dst.sendall(data)
        except OSError:
            pass
        self.close()

    def close(self) -> None:
        for s in self._socks:
            try:
                s.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            s.close()
        self._srv.close()


@pytest.fixture
def sim() -> Iterator[PioneerSim]:
    with PioneerSim("p3dx", time_scale=1.0, watchdog_s=1.0) as simulator:
        simulator.serve_tcp("127.0.0.1", 0)
        yield simulator


def test_a_raising_listener_kills_nothing(sim: PioneerSim) -> None:
    """Fault 1: `dump | head` made the printing listener raise BrokenPipeError, which killed
    the reader and keep-alive threads; the watchdog then stopped the robot."""
    assert sim.url is not None

    def broken_pipe(direction: str, payload: bytes, t: float) -> None:
        raise BrokenPipeError(32, "Broken pipe")

    with Pioneer.connect(sim.url) as robot:
        robot.add_listener(broken_pipe)
        robot.enable_motors()
        robot.set_velocity(0.1, 0.0)
        first = robot.wait_for_sip().sip_count
        time.sleep(2.0)  # twice the simulator's 1 s watchdog: only the keep-alive holds it off
        state = robot.wait_for_sip()
        truth = sim.snapshot()
        assert robot.alive and state.sip_count >= first + 15
        assert truth.trans_vel_set == pytest.approx(0.1) and truth.watchdog_trips == 0
        assert robot.stats.listener_errors > 20 and robot.stats.keepalives >= 3
    s = sim.wait_until(
        lambda s: not s.session_open and s.trans_vel_set == 0 and not s.motors_enabled, timeout=30
    )
    assert {"VEL", "RVEL", "ENABLE", "CLOSE"} <= set(s.commands)


def test_a_peer_that_does_not_read_cannot_hold_close(sim: PioneerSim) -> None:
    """Fault 2: a peer that sends SIPs but stops reading blocked sendall with the write lock
    held; close() had not returned after 15 s."""
    assert sim.url is not None
    relay = Relay(sim.url)
    robot = Pioneer.connect(relay.url, sip_timeout=30)
    relay.reading.clear()
    with pytest.raises(TransportError):  # the buffers fill, then a write misses its deadline
        for _ in range(200_000):
            robot.say([(0.02, 60)] * 20)
    start = time.monotonic()
    robot.close()
    assert time.monotonic() - start < 10.0  # bounded by close_timeout (2 s); it hung 15 s+
    relay.close()


def test_link_lost_during_request_config_raises(sim: PioneerSim) -> None:
    """Fault 3: request_config() returned the handshake's CONFIG when the link dropped."""
    assert sim.url is not None
    config_request = arcos.encode_command(arcos.Command.CONFIG, 1)
    relay = Relay(sim.url)
    with Pioneer.connect(relay.url) as robot:
        assert robot.request_config()["subtype"] == "p3dx"
        relay.cut_on = config_request
        with pytest.raises(ConnectionLost):
            robot.request_config(timeout=2.0)
        assert not robot.alive


def test_link_lost_names_the_url_once(sim: PioneerSim) -> None:
    """It said ``tcp://...: link lost (tcp://...: connection closed by the peer)``."""
    assert sim.url is not None
    relay = Relay(sim.url)
    with Pioneer.connect(relay.url) as robot:
        relay.cut_on = arcos.encode_command(arcos.Command.CONFIG, 1)
        with pytest.raises(ConnectionLost) as info:
            robot.request_config(timeout=5.0)
        with pytest.raises(ConnectionLost) as later:
            robot.wait_for_sip()
    for err in (info.value, later.value):  # (a keep-alive's write may find the loss first)
        assert str(err).startswith(f"{relay.url}: ") and str(err).count("tcp://") == 1, err


def test_a_bug_in_a_client_thread_fails_closed(sim: PioneerSim) -> None:
    """An unexpected exception in the reader stops the robot and reaches the caller with
    its own type and traceback; nothing hangs."""
    assert sim.url is not None

    class Buggy(Pioneer):
        def _on_sip(self, frame: bytes, now: float) -> None:
            if self.stats.sips >= 5:
                raise KeyError("a bug in the SIP handler")
            super()._on_sip(frame, now)

    robot = Buggy.connect(sim.url)
    robot.enable_motors()
    robot.set_velocity(0.1, 0.0)
    with pytest.raises(KeyError, match="a bug"):
        for _ in range(50):
            robot.wait_for_sip(timeout=10)
    assert not robot.alive
    sim.wait_until(lambda s: s.trans_vel_set == 0, timeout=30)
    robot.close()
    assert not robot._session.stuck_threads


def test_frames_arriving_during_a_request_are_still_handled(sim: PioneerSim) -> None:
    """Leader/follower: while callers read their own replies back to back, SIPs keep
    being decoded (by whichever thread holds the read)."""
    assert sim.url is not None
    with Pioneer.connect(sim.url) as robot:
        first = robot.stats.sips
        end = time.monotonic() + 0.6
        replies = 0
        while time.monotonic() < end:
            robot.request_config(timeout=1.0)
            replies += 1
        assert replies > 20 and robot.stats.sips >= first + 4
        assert robot.stats.as_dict()["received"]["CONFIG"] >= replies


def test_stats_are_consistent_and_short_to_print(sim: PioneerSim) -> None:
    assert sim.url is not None
    with Pioneer.connect(sim.url) as robot:
        robot.wait_for_sip()
        text = repr(robot.stats)
        data = robot.stats.as_dict()
    assert len(text) < 400 and "sips=" in text
    # SYNC1 and OPEN share command number 1, so the handshake counts two of them
    assert data["sips"] >= 1 and data["sent"]["OPEN"] == 2 and data["sent"]["CONFIG"] >= 1
    assert data["listener_errors"] == 0 and data["write_timeouts"] == 0


def test_a_second_client_is_told_the_robot_is_busy(sim: PioneerSim) -> None:
    """The serving layer refuses a second client of a single-client robot with a reason
    line; the client shows it as a DeviceError (exit code 4)."""
    from robocli.errors import DeviceError

    assert sim.url is not None
    with Pioneer.connect(sim.url):
        with pytest.raises(DeviceError, match="robot busy") as info:
            Pioneer.connect(sim.url, timeout=2.0)
    assert info.value.exit_code == 4


def test_concurrent_callers_and_the_reader_share_the_link(sim: PioneerSim) -> None:
    """Three threads requesting CONFIG at once: each gets its own reply, and when they stop
    the reader thread takes the SIPs again (it is not left parked)."""
    assert sim.url is not None
    errors: list[BaseException] = []
    with Pioneer.connect(sim.url) as robot:

        def hammer() -> None:
            try:
                for _ in range(100):
                    assert robot.request_config(timeout=2.0)["subtype"] == "p3dx"
            except BaseException as exc:
                errors.append(exc)

        run_together(hammer, 3, timeout=30)
        assert not errors
        count = robot.stats.sips
        robot.wait_for_sip(timeout=10)
        robot.wait_for_sip(timeout=10)
        assert robot.stats.sips >= count + 2 and robot._session._leaders == 0
