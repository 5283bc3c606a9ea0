"""The client's simulated laser and simulator status: scans reassembled from recorded AMRISim
packets (trace h, k) and against the built-in simulator over TCP, SIMSTAT (trace i)."""

from __future__ import annotations

import math
import re
import socket
import threading
import time
import tracemalloc
from collections.abc import Iterator

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robocli import Pioneer
from robocli.devices.pioneer import LaserScan
from robocli.devices.pioneer.laser import (
    MAX_READINGS,
    LaserSettings,
    ScanAssembler,
    parse_simstatus,
)
from robocli.errors import InvalidArgument, ProtocolError, TimeoutError
from robocli.io.capture import read_capture
from robocli.protocols import arcos
from robocli.sim.pioneer.server import PioneerSim
from robocli.sim.world import World
from tests import paths
from tests.devices.pioneer.test_pioneer_replay import frames_from
from tests.waiting import wait_for

DATA = paths.DATA / "arcos"
WALL_X = 2.0  #: m: a wall across the robot's path, from y = -5 to 5
BOSTON = (42.3601, -71.0589, 10.0)


def recorded_rx(stem: str) -> list[tuple[float, bytes]]:
    return [
        (f.t or 0.0, arcos.unframe(f.frame))
        for f in read_capture(DATA / f"{stem}.jsonl")
        if f.direction == "rx"
    ]


def assemble(packets: list[bytes], settings: LaserSettings) -> tuple[list[LaserScan], dict]:
    counts: dict[str, int] = {"laser_scans": 0, "laser_dropped": 0}
    asm = ScanAssembler(lambda name: counts.__setitem__(name, counts[name] + 1))
    out = []
    for p in packets:
        if p[0] not in (arcos.PacketType.SIM_LASER, arcos.PacketType.SIM_LASER_A):
            continue
        scan = asm.feed(p[0], p[1:], 0.0, (0.0, 0.0, 0.0), settings)
        if scan is not None:
            out.append(scan)
    return out, counts


def expected_wall(angle: float, x: float = 0.0) -> float:
    """Range from (x, 0) heading +x to the wall x = WALL_X (|y| <= 5), inf if missed."""
    if math.cos(angle) <= 1e-9:
        return math.inf
    r = (WALL_X - x) / math.cos(angle)
    return r if abs(r * math.sin(angle)) <= 5.0 else math.inf


@pytest.fixture
def wall_sim() -> Iterator[PioneerSim]:
    world = World.from_segments([(WALL_X, -5.0, WALL_X, 5.0)])
    with PioneerSim("p3dx", time_scale=5.0, world=world, georef=BOSTON) as sim:
        sim.serve_tcp("127.0.0.1", 0)
        yield sim


# ============================================================================ recorded packets


def test_trace_h_scans_reassemble_field_by_field() -> None:
    """Every 0x61 packet of the vendor SDK session: 111 complete scans, none dropped, ranges
    and reflectance equal to the recording's own decoded listing."""
    rx = recorded_rx("h_laser_wander")
    scans, counts = assemble([p for _, p in rx], LaserSettings())
    assert len(scans) == counts["laser_scans"] == 111 and counts["laser_dropped"] == 0
    listing = (DATA / "h_laser_wander.txt").read_text()
    checked = 0
    for m in re.finditer(
        r"#   scan (\d+) ranges: ([\d ]+)\n#   scan \1 reflectance: ([\d ]+)", listing
    ):
        scan = scans[int(m.group(1)) - 1]
        want = [int(v) for v in m.group(2).split()]
        assert [round(r * 1000) for r in scan.ranges] == want
        assert list(scan.reflectance or ()) == [int(v) for v in m.group(3).split()]
        checked += 1
    assert checked >= 5
    first = scans[0]
    assert len(first) == 181 and first.angles[0] == pytest.approx(-math.pi / 2)
    assert first.angles[90] == pytest.approx(0.0) and first.angles[-1] == pytest.approx(math.pi / 2)
    assert set(first.reflectance[78:105]) == {32}  # the map's reflector [h]
    assert not any(s.moved for s in scans)


def test_trace_k_plain_and_extended_scans_and_the_moved_flag() -> None:
    rx = [p for _, p in recorded_rx("k_laser_newcmds")]
    scans, counts = assemble(rx, LaserSettings(-45, 45, 50))
    assert counts == {"laser_scans": 46, "laser_dropped": 0}  # 26 plain + 20 extended [k]
    plain = [s for s in scans if s.reflectance is None]
    assert len(plain) == 26 and len(plain[0]) == 181
    assert [math.degrees(a) for a in plain[0].angles[:3]] == pytest.approx([-45.0, -44.5, -44.0])
    assert sum(s.moved for s in scans) == 1


def test_garbled_and_incomplete_scans_are_dropped_and_counted() -> None:
    rx = [p for _, p in recorded_rx("h_laser_wander") if p[0] == arcos.PacketType.SIM_LASER]
    one = rx[:6]
    settings = LaserSettings()
    _, c = assemble(one[:3] + one, settings)  # a scan abandoned half-way, then a whole one
    assert c == {"laser_scans": 1, "laser_dropped": 1}
    _, c = assemble(one[:2] + one[3:] + one, settings)  # a packet lost mid-scan
    assert c == {"laser_scans": 1, "laser_dropped": 1}
    _, c = assemble(one[1:] + one, settings)  # joined mid-scan: the tail belongs to no scan
    assert c == {"laser_scans": 1, "laser_dropped": 1}
    huge = arcos.unframe(arcos.encode_laser_scan([1000] * 32, extended=True))
    huge = huge[:1] + (MAX_READINGS + 1).to_bytes(2, "little") + huge[3:]  # total too large
    _, c = assemble([huge, *one], settings)
    assert c == {"laser_scans": 1, "laser_dropped": 1}
    asm = ScanAssembler()
    asm.feed(one[0][0], one[0][1:], 0.0, (0.0, 0.0, 0.0), settings)
    with pytest.raises(ProtocolError):
        asm.feed(one[1][0], one[1][1:-3], 0.0, (0.0, 0.0, 0.0), settings)  # truncated


def test_simstatus_of_trace_i_in_si_units() -> None:
    body = next(p for _, p in recorded_rx("i_simstat") if p[0] == arcos.PacketType.SIM_STAT)
    status = parse_simstatus(body[1:], 1.0)
    assert status.true_pose == (0.0, 0.0, 0.0)
    assert (status.sim_interval, status.real_interval) == (0.1, 0.1)
    assert status.gps is not None and status.gps.dop == 1.0
    assert status.gps.latitude == pytest.approx(42.3589333) and status.gps.altitude == -108.14
    assert status.odometry_error is not None and abs(status.odometry_error[0]) < 0.0075
    with pytest.raises(ProtocolError):
        parse_simstatus(body[1:-1], 1.0)


@pytest.mark.parametrize(
    ("th_deg", "expected_deg"), [(-5205, -165), (180, -180), (-180, -180), (725, 5), (90, 90)]
)
def test_simstatus_heading_is_normalised(th_deg: int, expected_deg: float) -> None:
    """AMRISim sends the true heading unwrapped (a robot that turned a while: -5205 deg);
    true_pose came out as -90.84 rad."""
    body = next(p for _, p in recorded_rx("i_simstat") if p[0] == arcos.PacketType.SIM_STAT)
    fields = {**arcos.decode_simstat(body[1:]), "th": th_deg}
    status = parse_simstatus(arcos.unframe(arcos.encode_simstat(fields))[1:], 1.0)
    th = status.true_pose[2]
    assert -math.pi <= th < math.pi and th == pytest.approx(math.radians(expected_deg))


# ============================================================================ built-in simulator


def test_laser_scan_sees_the_wall_at_its_distance(wall_sim: PioneerSim) -> None:
    assert wall_sim.url is not None
    with Pioneer.connect(wall_sim.url, laser=True) as robot:
        assert robot.is_simulator
        scan = robot.sim.wait_for_laser(timeout=5.0)
        assert robot.sim.laser is scan and len(scan) == 181
        assert [math.degrees(a) for a in scan.angles] == pytest.approx(list(range(-90, 91)))
        for a, r in zip(scan.angles, scan.ranges, strict=True):
            want = expected_wall(a)
            assert r == pytest.approx(want, abs=0.006) if math.isfinite(want) else math.isinf(r)
        nearest = scan.nearest()
        assert nearest is not None and nearest[0] == pytest.approx(WALL_X, abs=0.006)
        assert abs(nearest[1]) <= math.radians(3)
        assert scan.reflectance == (0,) * 181 and scan.pose == pytest.approx((0.0, 0.0, 0.0))
        assert all(x == pytest.approx(WALL_X, abs=0.006) for x, _ in scan.points())


def test_laser_commands_each_reach_the_listeners(wall_sim: PioneerSim) -> None:
    """start_laser writes its four commands in one write, as the vendor SDK does; listeners
    (and so `dump` and its recordings) still see every one, in order."""
    assert wall_sim.url is not None
    sent: list[tuple[int, int]] = []

    def listener(direction: str, payload: bytes, t: float) -> None:
        if direction == "tx" and payload[0] in (35, 36, 37, 38):
            cmd = arcos.decode_command(payload)
            sent.append((cmd.command, cmd.arg))

    with Pioneer.connect(wall_sim.url, listeners=[listener]) as robot:
        robot.sim.start_laser(math.radians(-45), math.radians(45), math.radians(0.5))
        assert len(robot.sim.wait_for_laser(timeout=5.0)) == 181  # the simulator got all four
        assert sent == [(36, -45), (37, 45), (38, 50), (35, 2)]
        assert robot.stats.as_dict()["sent"].get("ADSEL", 0) >= 1


def test_scan_pose_follows_the_robot_and_teleports_are_flagged(wall_sim: PioneerSim) -> None:
    assert wall_sim.url is not None
    with Pioneer.connect(wall_sim.url, laser=True) as robot:
        robot.enable_motors()
        robot.move(0.5)
        wall_sim.wait_until(lambda s: s.odom_x > 0.49 and s.trans_vel == 0.0, timeout=10)
        robot.wait_for_sip()
        scan = robot.sim.wait_for_laser()
        assert scan.pose == pytest.approx(robot.pose, abs=0.002)
        assert scan.pose[0] == pytest.approx(0.5, abs=0.01)
        assert scan.ranges[90] == pytest.approx(WALL_X - 0.5, abs=0.01)
        seen: list[LaserScan] = []
        robot.add_listener(seen.append, kind="laser")
        robot.sim.set_pose(1.0, 0.0, 0.0)  # the true pose only: odometry stays at 0.5
        while not any(s.moved for s in seen):
            robot.sim.wait_for_laser()
        moved = next(s for s in seen if s.moved)
        assert moved.ranges[90] == pytest.approx(WALL_X - 1.0, abs=0.01)
        assert moved.pose[0] == pytest.approx(0.5, abs=0.01)
        robot.sim.wait_for_laser()
        assert sum(s.moved for s in seen) == 1


def test_plain_scans_with_the_new_commands_then_off(wall_sim: PioneerSim) -> None:
    assert wall_sim.url is not None
    with Pioneer.connect(wall_sim.url) as robot:
        assert robot.sim.laser is None
        robot.sim.start_laser(-math.pi / 4, math.pi / 4, math.radians(0.5), extended=False,
                          new_commands=True)  # fmt: skip
        scan = robot.sim.wait_for_laser(timeout=5.0)
        assert len(scan) == 181 and scan.reflectance is None
        assert math.degrees(scan.angles[1] - scan.angles[0]) == pytest.approx(0.5)
        assert wall_sim.snapshot().laser_mode == 1
        robot.sim.stop_laser(new_commands=True)
        wall_sim.wait_until(lambda s: s.laser_mode == 0, timeout=30)
        n = robot.stats.laser_scans
        for _ in range(3):
            robot.wait_for_sip()
        assert robot.stats.laser_scans <= n + 1
        with pytest.raises(InvalidArgument):
            robot.sim.start_laser(resolution=0.0)
        with pytest.raises(InvalidArgument):
            robot.sim.start_laser(start=math.nan)


def test_a_raising_laser_listener_is_isolated(wall_sim: PioneerSim) -> None:
    assert wall_sim.url is not None
    with Pioneer.connect(wall_sim.url, laser=True) as robot:
        got: list[LaserScan] = []
        done = threading.Event()

        def bad(scan: LaserScan) -> None:
            raise RuntimeError("listener bug")

        def good(scan: LaserScan) -> None:
            got.append(scan)
            if len(got) >= 3:
                done.set()

        robot.add_listener(bad, kind="laser")
        robot.add_listener(good, kind="laser")
        assert done.wait(5.0)
        assert robot.stats.listener_errors >= 3 and robot.alive
        robot.remove_listener(bad, kind="laser")
        robot.sim.wait_for_laser()  # a notification under way when it was removed has ended
        errors = robot.stats.listener_errors
        robot.sim.wait_for_laser()
        robot.sim.wait_for_laser()
        assert robot.stats.listener_errors == errors
        assert robot.stats.laser_dropped == 0 and robot.stats.laser_scans >= 5


def test_sim_status_true_pose_and_gps(wall_sim: PioneerSim) -> None:
    assert wall_sim.url is not None
    with Pioneer.connect(wall_sim.url) as robot:
        robot.sim.set_pose(1.0, -0.5, math.pi / 2)
        wall_sim.wait_until(lambda s: s.x == 1.0, timeout=30)
        status = robot.sim.status()
        assert status.true_pose == pytest.approx((1.0, -0.5, math.pi / 2))
        assert robot.pose == pytest.approx((0.0, 0.0, 0.0))  # odometry unchanged
        assert status.gps is not None
        assert status.gps.longitude - BOSTON[1] == pytest.approx(122e-7, abs=2e-7)
        assert status.gps.latitude - BOSTON[0] == pytest.approx(-45e-7, abs=2e-7)
        assert status.sim_interval == 0.1 and status.real_interval == pytest.approx(0.02)
        robot.config = {**(robot.config or {}), "serial": "1234"}  # a real robot's CONFIG
        robot.identity = type(robot.identity)("Pioneer", "Pioneer", "p3dx")
        assert not robot.is_simulator
        assert robot.sim is None  # a real robot offers none of the simulator's calls


def test_without_georeference_there_is_no_gps(empty_sim: PioneerSim) -> None:
    assert empty_sim.url is not None
    with Pioneer.connect(empty_sim.url) as robot:
        status = robot.sim.status()
        assert status.gps is None and status.fields["gps_dop"] == -1
        with pytest.raises(TimeoutError):
            robot.sim.wait_for_laser(timeout=0.3)  # laser not started


@settings(max_examples=300, suppress_health_check=[HealthCheck.too_slow], deadline=None)
@given(st.sampled_from([0x60, 0x61]), st.binary(max_size=260), st.binary(max_size=60))
def test_decoders_and_assembler_raise_only_protocol_errors(
    ptype: int, body: bytes, stat: bytes
) -> None:
    asm = ScanAssembler()
    for decode in (
        lambda: arcos.decode_laser(ptype, body),
        lambda: asm.feed(ptype, body, 0.0, (0.0, 0.0, 0.0), LaserSettings()),
        lambda: parse_simstatus(stat, 0.0),
        lambda: arcos.decode_seto(bytes((7,)) + stat),
        lambda: arcos.decode_body(ptype, body),
    ):
        try:
            decode()
        except ProtocolError:
            pass


def test_assembler_memory_stays_bounded_under_a_garbled_flood() -> None:
    """Scans that never end, restart, or jump around: what is held stays one scan at most."""

    def packet(total: int, first: int) -> bytes:
        body = arcos.unframe(arcos.encode_laser_scan([1234] * 32, extended=True))
        return body[:1] + total.to_bytes(2, "little") + first.to_bytes(2, "little") + body[5:]

    dropped = []
    asm = ScanAssembler(dropped.append)
    settings = LaserSettings()
    tracemalloc.start()
    try:
        for round_ in range(3):
            for first in range(0, MAX_READINGS - 32, 32):  # the largest scan, never ended
                p = packet(MAX_READINGS, first)
                assert asm.feed(p[0], p[1:], 0.0, (0.0, 0.0, 0.0), settings) is None
            p = packet(MAX_READINGS + 1, 0)  # too large: refused, with all its packets
            for first in range(0, 20 * 32, 32):
                p = packet(MAX_READINGS + 1, first)
                assert asm.feed(p[0], p[1:], 0.0, (0.0, 0.0, 0.0), settings) is None
            for first in (0, 64, 32, 0, 96):  # out of order and restarts
                p = packet(4000 + round_, first)
                asm.feed(p[0], p[1:], 0.0, (0.0, 0.0, 0.0), settings)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 2 * 1024 * 1024  # one 8192-reading scan of packets (~0.5 MiB), no backlog
    # per round: the unfinished scan, the refused one, the 0-64 jump and the 0-96 jump
    assert dropped.count("laser_dropped") == 3 * 4 and "laser_scans" not in dropped


def test_client_against_amrisims_recorded_stream() -> None:
    """A scripted server answers the handshake and CONFIG with trace h's replies, then sends
    everything AMRISim sent after them (SIPs, each followed by its six 0x61 packets) over a
    real socket: the client completes every scan, drops none, and gives each the odometric
    pose of the SIP before it."""
    frames = [f.frame for f in read_capture(DATA / "h_laser_wander.jsonl") if f.direction == "rx"]
    at = next(i for i, f in enumerate(frames) if f[3] == arcos.PacketType.CONFIG) + 1
    replies, stream = frames[:at], frames[at:]
    srv = socket.create_server(("127.0.0.1", 0))
    listening = threading.Event()  # the first scan waits for the test's laser listener

    def serve() -> None:
        conn, _ = srv.accept()
        pending = list(replies)
        with conn:
            incoming = frames_from(conn)
            for frame in incoming:
                if frame[3] in (0, 1, 2, arcos.Command.CONFIG):
                    conn.sendall(pending.pop(0))
                if not pending:
                    break
            else:
                return  # the client left during the handshake
            for frame in stream:
                if frame[3] == arcos.PacketType.SIP:
                    time.sleep(0.002)
                elif not listening.is_set():  # connect() returned on the first SIP
                    listening.wait(10.0)
                conn.sendall(frame)
            conn.settimeout(30.0)
            for _ in incoming:  # the client's keep-alives, until it closes
                pass

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    poses: list[tuple[float, float]] = []
    with Pioneer.connect(f"tcp://127.0.0.1:{srv.getsockname()[1]}", subtype="p3dx") as robot:
        assert robot.is_simulator  # serial SIM, name AMRISim
        robot.add_listener(lambda scan: poses.append(scan.pose[:2]), kind="laser")
        listening.set()
        # the last scan's packets come after the last SIP
        wait_for(lambda: robot.stats.laser_scans >= 111, "the 111 scans")
        assert robot.stats.laser_scans == 111 and robot.stats.laser_dropped == 0
        assert robot.stats.decode_errors == 0
    thread.join(5.0)
    srv.close()
    sip_x = []  # the odometric x of the SIP before each scan, in metres
    last = 0.0
    for f in stream:
        if f[3] == arcos.PacketType.SIP:
            last = arcos.decode_sip(f[4:-2])["x"] * 0.485 / 1000.0
        elif f[3] == arcos.PacketType.SIM_LASER and f[6:8] == b"\x00\x00":  # first = 0
            sip_x.append(last)
    assert len(poses) == len(sip_x) == 111
    assert [x for x, _ in poses] == pytest.approx(sip_x, abs=0.001)
    assert max(sip_x) > 1.0  # the robot wandered
