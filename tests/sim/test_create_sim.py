"""The iRobot Create 2 simulator: pycreate2 (a third-party toolkit, unmodified) over a pty,
the OI's modes and safety rules, the stream, resynchronisation after garbage, TCP.

Raw clients here build their bytes with ``robocli.protocols.create_oi`` (checked against the
specification's vectors in tests/protocols/test_create_oi.py) and read the simulator's
truth with :meth:`CreateSim.wait_until`: every wait is on an event, with a deadline.
"""

from __future__ import annotations

import json
import math
import os
import select
import socket
import subprocess
import sys
import time
from collections.abc import Iterator

import pytest

from robocli.protocols import create_oi as oi
from robocli.protocols.create_oi import Op
from robocli.sim.create import CreateSim, CreateSimState
from robocli.sim.world import World
from tests.paths import DATA

pytest.importorskip("pycreate2")

DRIVER = DATA / "create" / "pycreate2_drive.py"
OFF, PASSIVE, SAFE, FULL = range(4)
WAIT = 10.0


class PtyClient:
    """The slave side of the simulator's pty, raw, as a toolkit opens it."""

    def __init__(self, path: str) -> None:
        import termios
        import tty

        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.fd, termios.TCSANOW)
        self.buf = bytearray()

    def send(self, *commands: bytes) -> None:
        os.write(self.fd, b"".join(commands))

    def read(self, n: int, timeout: float = WAIT) -> bytes:
        end = time.monotonic() + timeout
        while len(self.buf) < n:
            left = end - time.monotonic()
            if left <= 0 or not select.select([self.fd], [], [], left)[0]:
                raise AssertionError(f"{len(self.buf)} of {n} bytes in {timeout} s")
            self.buf += os.read(self.fd, 4096)
        out = bytes(self.buf[:n])
        del self.buf[:n]
        return out

    def close(self) -> None:
        os.close(self.fd)


def cmd(op: Op, **params: object) -> bytes:
    return oi.build_command(op, **params)


@pytest.fixture
def walled() -> Iterator[CreateSim]:
    """A Create 0.5 m from a wall ahead (x = 0.67), in the Pioneer simulator's world type."""
    world = World.from_segments([(0.67, -2.0, 0.67, 2.0)], name="wall")
    with CreateSim(world=world, start_pose=(0.0, 0.0, 0.0), time_scale=2.0) as sim:
        yield sim


@pytest.fixture
def pty_sim(walled: CreateSim) -> Iterator[tuple[CreateSim, PtyClient]]:
    client = PtyClient(walled.serve_pty())
    try:
        yield walled, client
    finally:
        client.close()


def test_pycreate2_drives_and_reads_its_odometry_unmodified() -> None:
    """pycreate2 starts, goes to safe mode, drives forward and turns left, reading group 100
    all along; the sums of its distance and angle packets agree with the simulator's truth
    (true pose and odometry), and its own clean-up puts the OI off."""
    with CreateSim() as sim:  # the default world: 7.5 m free ahead of the start
        path = sim.serve_pty()
        x0, y0, th0 = (lambda s: (s.x, s.y, s.th))(sim.snapshot())
        run = subprocess.run(
            [sys.executable, str(DRIVER), path], capture_output=True, text=True, timeout=120
        )
        assert run.returncode == 0, run.stderr
        got = json.loads([ln for ln in run.stdout.splitlines() if ln.startswith("{")][-1])
        end = sim.wait_until(lambda s: s.mode == OFF, WAIT)  # pycreate2's stop (173)
    assert got["modes"] == [SAFE] and got["reads"] > 10
    assert abs(got["distance"] - end.distance_mm) <= 1.0
    assert abs(got["angle"] - end.angle_deg) <= 1.0
    assert got["distance"] >= 300 and got["angle"] >= 90
    moved = math.hypot(end.x - x0, end.y - y0) * 1000.0  # turning in place adds no path
    assert abs(moved - got["distance"]) <= 2.0
    assert abs(math.degrees(end.th - th0) - got["angle"]) <= 1.0
    assert got["voltage"] == end.battery_mv and got["charge"] == end.battery_mah
    assert end.commands["DRIVE_DIRECT"] >= 3 and end.commands["SONG"] >= 4
    assert end.songs == 4 and end.played  # songs accepted and played (pycreate2's clear)
    assert end.dropped_bytes == 0


def _drive_into_the_wall(sim: CreateSim, client: PtyClient, mode: Op) -> CreateSimState:
    client.send(cmd(Op.START), cmd(mode), cmd(Op.DRIVE_DIRECT, right=200, left=200))
    return sim.wait_until(lambda s: s.bumps_drops & 3 == 3, WAIT)  # a head-on bump: both


def test_a_bump_in_safe_mode_stops_the_wheels_and_falls_back_to_passive(
    pty_sim: tuple[CreateSim, PtyClient],
) -> None:
    sim, client = pty_sim
    _drive_into_the_wall(sim, client, Op.SAFE)
    s = sim.wait_until(lambda s: s.mode == PASSIVE, WAIT)
    assert s.safety_trips == 1 and s.set_left == s.set_right == 0.0
    assert s.left == s.right == 0.0 and 0.4 < s.x < 0.51  # against the wall (radius 0.17)
    client.send(cmd(Op.DRIVE_DIRECT, right=200, left=200))  # passive: ignored
    s = sim.wait_until(lambda s: s.commands["DRIVE_DIRECT"] == 2, WAIT)
    assert s.ignored == 1 and s.set_left == 0.0
    client.send(cmd(Op.SENSORS, packet=7), cmd(Op.SENSORS, packet=35))  # sensors in passive
    assert client.read(2) == bytes([3, PASSIVE])
    # back in safe mode, pressed: not a new bump; backing away is allowed
    client.send(cmd(Op.SAFE), cmd(Op.DRIVE, velocity=-100, radius=oi.DRIVE_STRAIGHT))
    s = sim.wait_until(lambda s: s.bumps_drops == 0 and s.x < 0.45, WAIT)
    assert s.mode == SAFE and s.safety_trips == 1


def test_a_bump_in_full_mode_does_not_stop_the_wheels(
    pty_sim: tuple[CreateSim, PtyClient],
) -> None:
    sim, client = pty_sim
    _drive_into_the_wall(sim, client, Op.FULL)
    client.send(cmd(Op.SENSORS, packet=35))
    assert client.read(1) == bytes([FULL])
    s = sim.snapshot()
    assert s.mode == FULL and s.safety_trips == 0 and s.set_left == s.set_right == 0.2


def test_a_wheel_drop_in_safe_mode_stops_the_wheels(
    pty_sim: tuple[CreateSim, PtyClient],
) -> None:
    sim, client = pty_sim
    client.send(cmd(Op.START), cmd(Op.SAFE), cmd(Op.DRIVE_DIRECT, right=-100, left=-100))
    sim.wait_until(lambda s: s.left < 0, WAIT)
    sim.lift(left=True, right=False)
    s = sim.wait_until(lambda s: s.mode == PASSIVE, WAIT)
    assert s.safety_trips == 1 and s.left == s.right == 0.0 and s.bumps_drops == 8
    client.send(cmd(Op.QUERY_LIST, packets=[7, 35]))
    assert client.read(2) == bytes([8, PASSIVE])


def test_modes_gate_the_commands(pty_sim: tuple[CreateSim, PtyClient]) -> None:
    """Off takes only start (sensors unanswered); passive answers sensors but ignores drive
    and LEDs; safe takes both; stop goes off again."""
    sim, client = pty_sim
    client.send(cmd(Op.SENSORS, packet=35), cmd(Op.DRIVE, velocity=100, radius=0))
    s = sim.wait_until(lambda s: s.ignored == 2, WAIT)
    assert s.mode == OFF and s.set_left == 0.0
    client.send(cmd(Op.START), cmd(Op.LEDS, bits=4, color=0, intensity=128),
                cmd(Op.SENSORS, packet=35))  # fmt: skip
    assert client.read(1) == bytes([PASSIVE]) and sim.snapshot().leds == (0, 0, 0)
    client.send(cmd(Op.SAFE), cmd(Op.LEDS, bits=4, color=0, intensity=128),
                cmd(Op.DRIVE, velocity=100, radius=1), cmd(Op.SENSORS, packet=35))  # fmt: skip
    assert client.read(1) == bytes([SAFE])
    s = sim.snapshot()
    assert s.leds == (4, 0, 128) and (s.set_left, s.set_right) == (-0.1, 0.1)  # CCW in place
    client.send(cmd(Op.STOP), cmd(Op.SENSORS, packet=35))
    s = sim.wait_until(lambda s: s.ignored == 4, WAIT)
    assert s.mode == OFF and s.set_left == s.set_right == 0.0


def test_garbage_is_dropped_counted_and_the_stream_resynchronises(
    pty_sim: tuple[CreateSim, PtyClient],
) -> None:
    sim, client = pty_sim
    garbage = b"\x00\x01\x02\x13\xff\x8c\x09"  # no opcodes, and a song 9 that cannot be
    client.send(garbage, cmd(Op.START), cmd(Op.SENSORS, packet=35))
    assert client.read(1) == bytes([PASSIVE])
    assert sim.snapshot().dropped_bytes == len(garbage)
    client.send(b"\x91\x00")  # a drive direct cut short: abandoned after the byte timeout
    sim.wait_until(lambda s: s.dropped_bytes == len(garbage) + 2, WAIT)
    client.send(cmd(Op.SENSORS, packet=35))
    assert client.read(1) == bytes([PASSIVE])
    assert sim.snapshot().commands["DRIVE_DIRECT"] == 0


def test_the_stream_sends_its_packets_every_15_ms_of_robot_time(
    pty_sim: tuple[CreateSim, PtyClient],
) -> None:
    """Stream frames (19, n, id + data..., checksum) of packets 7, 19, 20 and 35; their
    distances sum to the odometry; one frame per 15 ms of robot time; pause stops it."""
    sim, client = pty_sim
    client.send(cmd(Op.START), cmd(Op.SAFE), cmd(Op.STREAM, packets=[7, 19, 20, 35]),
                cmd(Op.DRIVE_DIRECT, right=100, left=100))  # fmt: skip
    size = 3 + 4 + 1 + 2 + 2 + 1
    dist = 0
    frames = [oi.parse_stream(client.read(size)) for _ in range(40)]
    for f in frames:
        assert [pid for pid, _ in f] == [7, 19, 20, 35]
        dist += f[1][1]["distance"]
    assert frames[-1][3][1]["oi_mode"] == SAFE and dist > 0
    client.send(cmd(Op.PAUSE_RESUME_STREAM, resume=0))
    a = sim.wait_until(
        lambda s: s.stream_frames > 0 and s.commands["PAUSE_RESUME_STREAM"] > 0, WAIT
    )
    b = sim.wait_until(lambda s: s.sim_time > a.sim_time + 0.3, WAIT)
    assert b.stream_frames == a.stream_frames  # paused
    client.send(cmd(Op.DRIVE_DIRECT, right=0, left=0))
    sim.wait_until(lambda s: s.left == 0.0, WAIT)
    client.send(cmd(Op.PAUSE_RESUME_STREAM, resume=1))
    start = sim.wait_until(lambda s: s.stream_frames > b.stream_frames, WAIT)
    later = sim.wait_until(lambda s: s.sim_time >= start.sim_time + 0.3, WAIT)
    ticks = round((later.sim_time - start.sim_time) / 0.015)
    assert later.stream_frames - start.stream_frames == ticks  # one frame per tick


def test_tcp_serves_one_client_and_refuses_a_second() -> None:
    with CreateSim(time_scale=4.0) as sim:
        host, port = sim.serve_tcp().removeprefix("tcp://").rsplit(":", 1)
        with socket.create_connection((host, int(port)), timeout=WAIT) as a:
            a.sendall(cmd(Op.START) + cmd(Op.SENSORS, packet=3))
            got = b""
            while len(got) < oi.packet_size(3):
                got += a.recv(64)
            battery = oi.decode_packets([3], got)
            assert battery["battery_capacity"] == 2696 and 13000 < battery["voltage"] <= 16000
            with socket.create_connection((host, int(port)), timeout=WAIT) as b:
                assert b.recv(256).startswith(b"robocli-refused: robot busy")


def test_a_stream_that_cannot_fit_its_byte_count_is_refused(
    pty_sim: tuple[CreateSim, PtyClient],
) -> None:
    """Four groups 100 make 324 bytes: n-bytes is one byte, so the request is ignored (the
    ticker would otherwise fail building the frame) and a fitting one still works."""
    sim, client = pty_sim
    client.send(cmd(Op.START), cmd(Op.STREAM, packets=[100, 100, 100, 100]))
    s = sim.wait_until(lambda s: s.bad_requests == 1, WAIT)
    assert s.stream is None
    client.send(cmd(Op.STREAM, packets=[100, 100, 100]))  # 243 bytes: fits
    frame = oi.parse_stream(client.read(3 + 243))
    assert [pid for pid, _ in frame] == [100, 100, 100]
