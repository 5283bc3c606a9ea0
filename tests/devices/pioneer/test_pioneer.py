"""The Pioneer client against the built-in simulator over real sockets and a pty."""

from __future__ import annotations

import math
import socket
import sys
import threading
import time
from typing import Any

import numpy as np
import pytest

from robocli.devices.pioneer import Pioneer, WatchdogTripped
from robocli.errors import (
    ConnectionLost,
    InvalidArgument,
    TimeoutError,
    TransportError,
    UnknownRobotError,
)
from robocli.protocols import arcos
from robocli.robots.pioneer import ROBOT_PARAMS
from robocli.sim.pioneer.server import PioneerSim
from robocli.sim.world import World
from robocli.transports import FaultyTransport, SocketTransport
from tests.paths import EXAMPLES

sys.path.insert(0, str(EXAMPLES))


def settle(sim: PioneerSim, robot: Pioneer) -> None:
    """Wait until the simulated robot is still, then for a SIP that shows it."""
    sim.wait_until(lambda s: abs(s.trans_vel) < 1e-9 and abs(s.rot_vel) < 1e-9, timeout=10)
    robot.wait_for_sip()
    robot.wait_for_sip()


def test_handshake_identity_config_and_motors_off(sim: PioneerSim) -> None:
    assert sim.url is not None
    with Pioneer.connect(sim.url) as robot:
        assert (robot.identity.name, robot.identity.type, robot.identity.subtype) == (
            "robocli-sim",
            "Pioneer",
            "p3dx",
        )
        assert robot.params is ROBOT_PARAMS["p3dx"]
        assert robot.config is not None and robot.config["watchdog"] == 2000
        state = robot.state
        assert not state.motors_enabled and state.sonar_enabled
        robot.enable_motors()
        assert robot.wait_for_sip().motors_enabled or robot.wait_for_sip().motors_enabled
    # the simulator handles the stop sequence on its own link thread: wait for it
    snap = sim.wait_until(lambda s: not s.session_open, 30)
    assert not snap.motors_enabled


def test_subtype_override_and_unknown_subtype(sim: PioneerSim) -> None:
    assert sim.url is not None
    with pytest.raises(UnknownRobotError, match="no parameters"):
        Pioneer.connect(sim.url, subtype="box")
    sim.wait_until(lambda s: s.clients == 0, 30)  # one client at a time: the first has left
    with Pioneer.connect(sim.url, subtype="p3dx-sh") as robot:
        assert robot.params.dist_conv == 1.0


def test_velocity_commands_reach_the_robot(sim: PioneerSim) -> None:
    assert sim.url is not None
    with Pioneer.connect(sim.url) as robot:
        robot.enable_motors()
        robot.set_velocity(0.3, math.radians(20))
        s = sim.wait_until(lambda s: s.trans_vel_set > 0, timeout=30)
        assert s.trans_vel_set == pytest.approx(0.3) and s.rot_vel_set == pytest.approx(
            math.radians(20)
        )
        state = robot.wait_for_sip()
        deadline = time.monotonic() + 5
        while state.v < 0.29 and time.monotonic() < deadline:
            state = robot.wait_for_sip()
        assert state.v == pytest.approx(0.3, abs=0.01)
        assert state.w == pytest.approx(math.radians(20), abs=0.01)
        robot.set_wheel_velocities(-0.2, 0.2)
        s = sim.wait_until(
            lambda s: abs(s.left_mm_s + 200) < 1 and abs(s.right_mm_s - 200) < 1, timeout=30
        )
        assert s.trans_vel == pytest.approx(0.0, abs=1e-3)
        robot.stop()
        settle(sim, robot)
        robot.set_digital_out(0b1010, 0b1000)
        robot.say([(0.1, 40), (0.2, 60)])
        robot.enable_sonar(False)
        s = sim.wait_until(lambda s: not s.sonar_enabled, timeout=30)
        assert (s.last_say, s.digout & 0b1010) == (((100, 40), (200, 60)), 0b1000)  # ms
        assert not robot.wait_for_sip().sonar_enabled or not robot.wait_for_sip().sonar_enabled


def test_move_heading_and_odometry_agree_with_the_truth(empty_sim: PioneerSim) -> None:
    assert empty_sim.url is not None
    with Pioneer.connect(empty_sim.url) as robot:
        robot.enable_motors()
        robot.move(1.0)
        empty_sim.wait_until(lambda s: s.trans_vel > 0.01, timeout=30)
        settle(empty_sim, robot)
        robot.set_heading(math.pi / 2)
        empty_sim.wait_until(lambda s: abs(s.rot_vel) > 0.01, timeout=30)
        settle(empty_sim, robot)
        truth = empty_sim.snapshot()
        x, y, th = robot.pose
        assert (x, y) == pytest.approx((truth.odom_x, truth.odom_y), abs=0.002)
        assert x == pytest.approx(1.0, abs=0.01) and th == pytest.approx(math.pi / 2, abs=0.01)


def test_odometry_unwraps_the_15_bit_counters(empty_sim: PioneerSim) -> None:
    """32768 units x 0.485 mm = 15.9 m: drive 20 m and the client pose must follow."""
    assert empty_sim.url is not None
    with Pioneer.connect(empty_sim.url) as robot:
        robot.enable_motors()
        robot.set_acceleration(2.0)
        robot.set_velocity(1.0, 0.0)
        raw = set()
        while robot.pose[0] < 20.0:
            state = robot.wait_for_sip()
            raw.add(empty_sim.snapshot().odom_raw[0] < 1000)
        robot.stop()
        settle(empty_sim, robot)
        assert raw == {True, False}  # the raw counter wrapped on the way
        assert robot.pose[0] == pytest.approx(empty_sim.snapshot().odom_x, abs=0.002)
        assert state.x > 16.0


def test_corrupted_stream_is_resynchronised_and_counted(sim: PioneerSim) -> None:
    assert sim.url is not None
    host, port = sim.url.removeprefix("tcp://").split(":")
    inner = SocketTransport.connect(host, int(port))
    faulty = FaultyTransport(inner, split=13, corrupt=0.002, seed=7)
    with Pioneer.from_transport(faulty, timeout=10) as robot:
        for _ in range(60):
            robot.wait_for_sip(timeout=10)
        assert faulty.corrupted > 0
        assert robot.stats.bad_checksums + robot.stats.dropped_bytes > 0
        assert robot.state.battery == pytest.approx(13.0, abs=0.5)  # no garbage got through
        x, y, _ = robot.pose
        assert abs(x) < 1e-6 and abs(y) < 1e-6


def test_keepalive_holds_the_watchdog_off_and_silence_trips_it() -> None:
    with PioneerSim("p3dx", watchdog_s=1.0, time_scale=5.0, world=World.empty()) as sim:
        url = sim.serve_tcp("127.0.0.1", 0)
        with Pioneer.connect(url, keepalive=0.4) as robot:
            robot.enable_motors()
            robot.set_velocity(0.2, 0.0)
            time.sleep(2.5)
            assert sim.snapshot().watchdog_trips == 0
            assert sim.snapshot().trans_vel_set == pytest.approx(0.2)
            gaps = np.diff(np.array(robot.stats.tx_times))
            # what the robot's watchdog sees: never 1 s of silence (the 0.4 s period itself
            # is a bench figure, `robocli bench sip`: a loaded machine wakes the thread late)
            assert gaps.size > 3 and gaps.max() < 1.0
            robot.keepalive = 1e9  # the program hangs: nothing goes out any more
            s = sim.wait_until(lambda s: s.watchdog_trips >= 1, timeout=30)
            s = sim.wait_until(lambda s: abs(s.trans_vel) < 1e-9, timeout=30)
            assert s.motors_enabled and s.session_open  # stopped, not disconnected
            with pytest.raises(WatchdogTripped, match="watchdog"):  # the program is told
                robot.set_velocity(0.1, 0.0)
            assert robot.stats.watchdog_trips == 1 and sim.snapshot().trans_vel_set == 0.0
            robot.set_velocity(0.1, 0.0)  # resumes on the next command
            assert sim.wait_until(lambda s: s.trans_vel > 0.05, timeout=30)


def test_deadman_stops_a_robot_the_program_forgot(sim: PioneerSim) -> None:
    assert sim.url is not None
    with Pioneer.connect(sim.url, deadman=0.3) as robot:
        robot.enable_motors()
        robot.set_velocity(0.2, 0.0)
        sim.wait_until(lambda s: s.trans_vel > 0.05, timeout=30)
        s = sim.wait_until(lambda s: s.trans_vel_set == 0.0, timeout=30)
        assert robot.stats.deadman_stops == 1 and s.session_open


def test_leaving_the_block_stops_the_robot(sim: PioneerSim) -> None:
    assert sim.url is not None
    with pytest.raises(RuntimeError):
        with Pioneer.connect(sim.url) as robot:
            robot.enable_motors()
            robot.set_velocity(0.3, 0.5)
            sim.wait_until(lambda s: s.trans_vel > 0.05, timeout=30)
            raise RuntimeError("the student's code failed")
    # the simulator's set-point settles on its next tick after CLOSE: wait for all three
    s = sim.wait_until(
        lambda s: not s.session_open and s.trans_vel_set == 0 and not s.motors_enabled,
        timeout=30,
    )
    assert {"VEL", "RVEL", "ENABLE", "CLOSE"} <= set(s.commands)


def test_lost_link_is_reported_to_the_caller() -> None:
    sim = PioneerSim("p3dx", time_scale=5.0)
    url = sim.serve_tcp("127.0.0.1", 0)
    with Pioneer.connect(url) as robot:
        robot.wait_for_sip()
        sim.close()
        with pytest.raises(ConnectionLost):
            for _ in range(50):
                robot.wait_for_sip(timeout=10)
        with pytest.raises(ConnectionLost):
            _ = robot.pose
        assert not robot.alive


def test_no_sip_raises_timeout_not_a_hang() -> None:
    """A robot that answers the handshake, then never sends a SIP."""
    srv = socket.create_server(("127.0.0.1", 0))

    def serve() -> None:
        conn, _ = srv.accept()
        with conn:
            while data := conn.recv(4096):
                for cmd in (0, 1, 2):
                    if data == arcos.encode_command(cmd):
                        reply = (
                            b""
                            if cmd < 2
                            else arcos.SyncReply.build(
                                {"name": "mute", "type": "Pioneer", "subtype": "p3dx"}
                            )
                        )
                        conn.sendall(arcos.frame(bytes((cmd,)) + reply))

    threading.Thread(target=serve, daemon=True).start()
    start = time.monotonic()
    with pytest.raises(TimeoutError, match="no SIP"):  # connect's timeout bounds it
        Pioneer.connect(f"tcp://127.0.0.1:{srv.getsockname()[1]}", timeout=1.0, sip_timeout=60)
    assert time.monotonic() - start < 30  # connect's 1 s, not the 60 s for later SIPs
    srv.close()


def test_serial_path_over_a_pty_and_a_session_left_open() -> None:
    """Serial semantics: a crashed client leaves the robot streaming SIPs; the next client
    finds SIPs in reply to SYNC0, sends CLOSE and re-syncs on the same line."""
    with PioneerSim("p3dx", time_scale=5.0) as sim:
        path = sim.serve_pty()
        first = Pioneer.connect(path, baudrate=9600)
        first.enable_motors()
        first.transport.close()  # a crash: the port goes away, no CLOSE goes out
        assert sim.snapshot().session_open and sim.snapshot().commands["CLOSE"] == 0
        with Pioneer.connect(path) as second:
            assert second.wait_for_sip().sip_count >= 1
            assert sim.snapshot().commands["CLOSE"] == 1  # the re-sync's
        # and the second client's own, once the simulator has read it
        sim.wait_until(lambda s: s.commands["CLOSE"] == 2, 30)
        first.close()


def test_unreachable_url_is_a_transport_error() -> None:
    with pytest.raises(TransportError):
        Pioneer.connect("/dev/robocli-no-such-port")


def test_wander_example_moves_2m_without_collision() -> None:
    """examples/wander.py against the default room: 30 s of simulated time."""
    from wander import wander

    with PioneerSim("p3dx", time_scale=10.0) as sim:
        url = sim.serve_tcp("127.0.0.1", 0)
        with Pioneer.connect(url) as robot:
            result = wander(robot, 300)
        truth = sim.snapshot()
    assert result.distance >= 2.0 and result.bumps == 0
    assert truth.sim_time >= 30.0 and not truth.stalled


def test_teleop_with_scripted_keys(sim: PioneerSim) -> None:
    from robocli.devices.pioneer.teleop import TeleopController, run_teleop

    keys = iter(["up"] * 20 + [None] * 15 + ["q"])
    assert sim.url is not None
    with Pioneer.connect(sim.url) as robot:
        robot.enable_motors()
        seen: list[tuple[float, float]] = []

        def read_key(timeout: float) -> str | None:
            time.sleep(timeout)
            return next(keys)

        run_teleop(
            robot,
            read_key,
            TeleopController(max_v=0.3, release_timeout=0.45),
            period=0.05,
            on_update=lambda v, w: seen.append((v, w)),
        )
        settle(sim, robot)
        assert robot.pose[0] > 0.05  # it drove forward, then stopped on release
    assert seen[0] == (0.3, 0.0) and seen[-1] == (0.0, 0.0)


def test_io_encoder_packets_and_odometry_reset(empty_sim: PioneerSim) -> None:
    assert empty_sim.url is not None
    with Pioneer.connect(empty_sim.url) as robot:
        robot.request_io(1)
        robot.request_encoders(1)
        for _ in range(5):
            robot.wait_for_sip()
            if robot.io is not None and robot.encoders is not None:
                break
        assert robot.io is not None and len(robot.io["digin"]) == 4
        assert robot.encoders == empty_sim.snapshot().encoder_ticks
        robot.enable_motors()
        robot.move(0.5)
        empty_sim.wait_until(lambda s: s.trans_vel > 0.01, timeout=30)
        settle(empty_sim, robot)
        assert robot.pose[0] == pytest.approx(0.5, abs=0.01)
        robot.reset_odometry()
        empty_sim.wait_until(lambda s: s.odom_raw == (0, 0, 0), timeout=30)
        robot.wait_for_sip()
        assert robot.pose == pytest.approx((0.0, 0.0, 0.0), abs=1e-9)


def test_bumping_a_wall_shows_in_the_state() -> None:
    wall = World.from_segments([(1.0, -5.0, 1.0, 5.0)])
    with PioneerSim("p3dx", time_scale=5.0, world=wall) as sim:
        url = sim.serve_tcp("127.0.0.1", 0)
        with Pioneer.connect(url) as robot:
            robot.enable_motors()
            robot.set_velocity(0.3, 0.0)
            state = robot.wait_for_sip()
            deadline = time.monotonic() + 10
            while not (state.bumped and state.stalled) and time.monotonic() < deadline:
                state = robot.wait_for_sip()
            assert state.bumpers_front and state.stalled and not state.bumpers_rear
            assert min(robot.sonar[2:6]) < 0.6  # the front sonars see the wall
            robot.set_velocity(-0.2, 0.0)
            while state.bumped and time.monotonic() < deadline:
                state = robot.wait_for_sip()
            assert not state.bumped


def test_sips_stopping_mid_session_raise_timeout() -> None:
    """The link stays open but the robot stops talking: the caller gets TimeoutError."""
    from tests.devices.pioneer.test_pioneer_replay import DATA, ReplayServer

    server = ReplayServer(DATA / "a_simpleConnect.jsonl")
    with Pioneer.connect(server.url, sip_timeout=0.5) as robot:
        with pytest.raises(TimeoutError, match="no SIP"):
            for _ in range(200):
                robot.wait_for_sip(timeout=2)
        with pytest.raises(TimeoutError):
            _ = robot.state


@pytest.mark.parametrize(
    ("option", "value"),
    [("timeout", math.inf), ("timeout", math.nan), ("timeout", 0.0), ("sip_timeout", -1.0),
     ("keepalive", "0.4"), ("timeout", 1e308)],
)  # fmt: skip
def test_durations_must_be_finite_positive_seconds(option: str, value: Any) -> None:
    """Checked before anything is opened: inf once reached socket.create_connection as an
    OverflowError traceback."""
    with pytest.raises(InvalidArgument, match=option):
        Pioneer.connect("tcp://127.0.0.1:9", **{option: value})
