"""The built-in simulator's laser against recorded AMRISim traces h (vendor SDK wander) and k
(the newer commands 230-233), over real sockets; the ray caster and scan geometry."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import pytest

from robocli.io.capture import read_capture
from robocli.protocols import arcos
from robocli.protocols.arcos import Command, PacketType
from robocli.sim.laser import LMS200, LaserGeometry, LaserSpec, cast, reflectance
from robocli.sim.pioneer.server import PioneerSim
from robocli.sim.world import World
from tests import paths

if TYPE_CHECKING:
    from tests.sim.conftest import RawClient

DATA = paths.DATA / "arcos"
MakeSim = Callable[..., PioneerSim]
Connect = Callable[[PioneerSim], "RawClient"]
LASER_TYPES = (PacketType.SIM_LASER_A, PacketType.SIM_LASER)


MAP = (DATA / "laser_room.map").read_text().splitlines()


def reflector() -> list[float]:
    """The map's ``Reflector`` line (m)."""
    line = next(line for line in MAP if line.startswith("Cairn: Reflector"))
    return [float(v) / 1000.0 for v in line.split()[-4:]]


def laser_room() -> World:
    """The map of traces h-k (a MobileSim ``.map``: the LINES section, mm), with its
    ``Reflector`` line, which Stage treats as an obstacle too."""
    start, end = MAP.index("LINES") + 1, MAP.index("DATA")
    segs = [[float(v) / 1000.0 for v in line.split()] for line in MAP[start:end]]
    return World.from_segments([*segs, reflector()], name="laser_room")


def trace_frames(stem: str, direction: str) -> list[tuple[float, bytes]]:
    """(time, payload) of one direction of a copied trace."""
    return [
        (f.t or 0.0, arcos.unframe(f.frame))
        for f in read_capture(DATA / f"{stem}.jsonl")
        if f.direction == direction
    ]


def scans(payloads: list[bytes]) -> list[list[arcos.LaserPacket]]:
    """Laser packets grouped into scans (a scan starts at ``first`` 0)."""
    out: list[list[arcos.LaserPacket]] = []
    for p in payloads:
        if p[0] in LASER_TYPES:
            pkt = arcos.decode_laser(p[0], p[1:])
            if pkt.first == 0 or not out:
                out.append([])
            out[-1].append(pkt)
    return out


def ranges_of(scan: list[arcos.LaserPacket]) -> list[int]:
    return [r for pkt in scan for r in pkt.ranges]


def shape(scan: list[arcos.LaserPacket]) -> list[tuple[int, int, int]]:
    return [(p.total, p.first, len(p.ranges)) for p in scan]


# ============================================================================ geometry


def test_geometry_follows_the_stage_rules() -> None:
    g = LaserGeometry()
    assert (g.fov, g.count) == (180.0, 181)
    b = np.degrees(g.bearings())
    assert b[0] == pytest.approx(-90.0) and b[-1] == pytest.approx(90.0)
    assert np.diff(b) == pytest.approx(np.ones(180))
    g.set_start(-45)
    g.set_end(45)
    assert g.count == 181  # a FOV change keeps the count (only the spacing changes)
    assert np.degrees(g.bearings())[[0, -1]] == pytest.approx([-45.0, 45.0])
    g.set_resolution(50)  # hundredths of a degree [k]
    assert g.count == 181 and np.diff(np.degrees(g.bearings())) == pytest.approx(0.5 * np.ones(180))
    g.set_start(0)
    g.set_end(180)  # only the width matters: still symmetric about the heading
    g.set_resolution(100)
    assert g.count == 181 and np.degrees(g.bearings())[0] == pytest.approx(-90.0)
    g.set_start(90)
    g.set_end(-90)  # end < start: reversed order
    assert np.degrees(g.bearings())[[0, -1]] == pytest.approx([90.0, -90.0])
    g.set_resolution(1)  # 0.01 deg over 180 deg: 18001 readings, capped
    assert g.count == arcos.LASER_MAX_TOTAL == len(g.bearings())
    assert np.degrees(g.bearings())[[0, -1]] == pytest.approx([90.0, -90.0])  # spacing widens
    g.set_resolution(0)
    assert g.count == 0 and len(g.bearings()) == 0


def test_cast_hits_a_wall_at_its_distance_and_inf_beyond_range() -> None:
    world = World.from_segments([(2.0, -10.0, 2.0, 10.0)])
    angles = np.radians([-60.0, -30.0, 0.0, 30.0, 60.0, 90.0, 180.0])
    r = cast(world, (0.0, 0.0, 0.0), angles, 32.0)
    assert r[:5] == pytest.approx(2.0 / np.cos(angles[:5]))
    assert np.isinf(r[5:]).all()  # parallel and away: no return
    # the robot's pose moves and turns the rays; max range cuts hits off; min range clamps
    r = cast(world, (1.0, 0.0, math.pi / 2), np.radians([-90.0]), 32.0)
    assert r == pytest.approx([1.0])
    assert np.isinf(cast(world, (0.0, 0.0, 0.0), [0.0], 1.5)).all()
    assert cast(world, (1.9, 0.0, 0.0), [0.0], 32.0, min_range=0.5) == pytest.approx([0.5])
    assert len(cast(World.empty(), (0.0, 0.0, 0.0), [0.0, 1.0], 32.0)) == 2


def test_reflectors_follow_the_lms200_rules() -> None:
    tape = [2.0, -10.0, 2.0, 10.0]
    world = World.from_segments([tape, (40.0, -1.0, 40.0, 1.0), (0.0, 3.0, 5.0, 3.0)])
    angles = np.radians([0.0, 40.0, 50.0, -40.0, 90.0, 180.0])
    r = cast(world, (0.0, 0.0, 0.0), angles, 32.0)
    # dead ahead and 40 deg off the normal: 32; 50 deg: 0; a wall that is not tape: 0
    assert reflectance([tape], (0.0, 0.0, 0.0), angles, r).tolist() == [32, 32, 0, 32, 0, 0]
    far = [40.0, -1.0, 40.0, 1.0]
    for x, want in ((5.0, 0), (15.0, 32)):  # 35 m away: too far (> 30 m); 25 m: seen
        r = cast(world, (x, 0.0, 0.0), [0.0], 40.0)
        assert reflectance([far], (x, 0.0, 0.0), [0.0], r).tolist() == [want]


# ============================================================================ vendor SDK (h)


def test_vendor_sdk_laser_sequence_is_served_like_amrisim(
    make_sim: MakeSim, connect: Connect
) -> None:
    """Replay ARIA's start-up from trace h (handshake, CONFIG, 31, the CONFIG echo, then
    36/37/38/35 in one chunk): every request is answered, and the first scan arrives before
    the second SIP after the laser request, shaped exactly as AMRISim's."""
    sent = trace_frames("h_laser_wander", "tx")
    enable_at = next(i for i, (_, p) in enumerate(sent) if p[0] == Command.ADSEL)
    sim = make_sim(name="AMRISim", world=laser_room(), time_scale=1.0,  # 100 ms, as ARIA
                   reflectors=[reflector()])  # fmt: skip
    client = connect(sim)
    replies = {0: 0, 1: 1, 2: 2}  # SYNC n -> reply n, then OPEN, CONFIG -> 0x20
    for _, payload in sent[:3]:
        client.send_raw(arcos.frame(payload))
        assert client.expect(replies[payload[0]])[0] == payload[0]
    for _, payload in sent[3 : enable_at - 3]:
        client.send_raw(arcos.frame(payload))
        if payload[0] == Command.CONFIG:
            cfg = arcos.parse_config(client.expect(PacketType.CONFIG)[1:])
            assert cfg["serial"] == "SIM"  # what makes ARIA ask for the simulated laser
    client.sip()
    client.flush()
    laser_cmds = [p for _, p in sent[enable_at - 3 : enable_at + 1]]
    assert [p[0] for p in laser_cmds] == [36, 37, 38, 35]
    client.send_raw(b"".join(arcos.frame(p) for p in laser_cmds))  # one chunk, as ARIA
    # the simulator's n-th SIP is the n-th this client received (one fresh session)
    at = sim.wait_until(lambda s: s.laser_mode == 2, 30).laser_enabled_at_sip
    while sum(1 for _, p in client.log if p[0] == PacketType.SIP) < at + 2:
        assert client.next(5.0) is not None, "the simulator went silent"
    log = [p for _, p in client.log]
    sip_at = [i for i, p in enumerate(log) if p[0] == PacketType.SIP]
    first_laser = next(i for i, p in enumerate(log) if p[0] in LASER_TYPES)
    assert sip_at[at] < first_laser < sip_at[at + 1]  # before the 2nd SIP after the request
    ours = scans(log[sip_at[at] : sip_at[at + 1]])
    assert len(ours) == 1, "one complete scan after the first SIP, before the second"
    state = sim.snapshot()
    assert state.laser_mode == 2 and state.commands["ADSEL"] == 1  # 35 = laser enable here
    assert state.commands["GRIPPERVAL"] == state.commands["GYROCALCW"] == 1

    theirs = scans([p for _, p in trace_frames("h_laser_wander", "rx")])
    assert len(theirs) == 111
    assert shape(ours[0]) == shape(theirs[0]) == [
        (181, 0, 32), (181, 32, 32), (181, 64, 32), (181, 96, 32), (181, 128, 32), (181, 160, 21)
    ]  # fmt: skip
    assert [p.flags for p in ours[0]] == [p.flags for p in theirs[0]] == [0] * 6
    # the same room seen from the same pose: AMRISim's rays are 0.9945 deg apart, ours 1 deg,
    # so compare where neighbouring readings agree (not across an edge); Stage ray-traces a
    # raster of the walls, so its ranges run about 2 cm short of the exact lines
    a, b = np.array(ranges_of(ours[0])), np.array(ranges_of(theirs[0]))
    smooth = np.abs(np.diff(b, prepend=b[0])) < 50
    assert 0 < np.median((a - b)[smooth]) < 35
    assert np.mean(np.abs(a - b)[smooth] < 60) > 0.9
    # reflectance 32 on the reflector, 0 elsewhere; the edges may move by one reading
    ra = [r for p in ours[0] for r in p.reflectance or ()]
    rb = [r for p in theirs[0] for r in p.reflectance or ()]
    assert set(ra) == set(rb) == {0, 32}
    on_a, on_b = [i for i, v in enumerate(ra) if v], [i for i, v in enumerate(rb) if v]
    assert abs(on_a[0] - on_b[0]) <= 1 and abs(on_a[-1] - on_b[-1]) <= 1


def test_every_cycle_has_one_complete_scan_after_its_sip(
    make_sim: MakeSim, connect: Connect
) -> None:
    sim = make_sim(world=laser_room(), time_scale=10.0)
    client = connect(sim)
    client.open_session()
    for cmd, arg in ((36, -90), (37, 90), (38, 100), (35, 2)):
        client.send(cmd, arg)
    client.expect(PacketType.SIM_LASER, 5.0)
    client.sip()
    got = client.collect(1.0)
    cycles: list[list[int]] = [[]]
    for p in got:
        if p[0] == PacketType.SIP:
            cycles.append([])
        cycles[-1].append(p[0])
    full = cycles[1:-1]  # whole cycles only
    assert len(full) >= 5
    assert all(c == [PacketType.SIP] + [PacketType.SIM_LASER] * 6 for c in full)
    # consecutive scans differ by the range noise (+-5 mm on hits, as the LMS200 model)
    s = scans(got)
    diff = np.array(ranges_of(s[1])) - np.array(ranges_of(s[2]))
    assert np.any(diff != 0) and np.all(np.abs(diff) <= 10)


# ============================================================================ new commands (k)


def test_new_commands_plain_then_extended_moved_flag_and_off(
    make_sim: MakeSim, connect: Connect
) -> None:
    """Trace k's sequence: 231 -45, 232 45, 233 50, 230 1 -> 0x60 scans of 181 readings
    with the odometric pose; 230 2 -> 0x61; SIM_SET_POSE -> the flag in one first packet;
    230 0 -> no more scans."""
    sent = [p for _, p in trace_frames("k_laser_newcmds", "tx")]
    setup = [p for p in sent if p[0] in (231, 232, 233, 230)][:4]
    assert [p[0] for p in setup] == [231, 232, 233, 230]
    sim = make_sim(world=laser_room(), time_scale=10.0, odom_noise=0.0)
    client = connect(sim)
    client.open_session(enable=True)
    client.send_raw(b"".join(arcos.frame(p) for p in setup))
    client.expect(PacketType.SIM_LASER_A, 5.0)
    client.send(Command.VEL, 200)
    sim.wait_until(lambda s: s.odom_x > 0.25, 10.0)
    client.send(Command.VEL, 0)
    sim.wait_until(lambda s: s.trans_vel == 0.0, 10.0)
    client.flush()
    got = client.collect(0.5)
    sip = arcos.decode_sip(next(p for p in got if p[0] == PacketType.SIP)[1:])
    plain = scans(got)[1]  # a whole scan sent after that SIP (the robot stands still)
    theirs = scans([p for _, p in trace_frames("k_laser_newcmds", "rx")])
    theirs_plain = [s for s in theirs if s[0].pose is not None]
    assert len(theirs_plain) == 26
    assert shape(plain) == shape(theirs_plain[0])
    raw = [p for p in got if p[0] == PacketType.SIM_LASER_A]
    assert {len(p) - 1 for p in raw} == {75, 53}  # data lengths [k]
    x_mm = sip["x"] * 0.485  # the 0x60 pose is the SIP's odometry in mm [k: 583 raw = 283]
    assert all(p.pose is not None and abs(p.pose[0] - x_mm) <= 1 for p in plain)
    assert all(p.pose == (plain[0].pose[0], 0, 0) for p in plain if p.pose is not None)
    np.testing.assert_allclose(
        np.array(ranges_of(plain)) / 1000.0,
        cast(laser_room(), (sim.snapshot().x, 0.0, 0.0), np.radians(np.arange(181) / 2 - 45), 33),
        atol=0.006,
    )

    client.send_raw(arcos.frame(next(p for p in sent if p[0] == 230 and p[2] == 2)))
    client.expect(PacketType.SIM_LASER, 5.0)
    client.send_raw(arcos.encode_sim_pose(500, 0, 0))
    got = client.collect(0.6)
    ext = [s for s in scans(got) if s[0].pose is None]
    flagged = [s for s in ext if s[0].flags & arcos.SIM_LASER_MOVED]
    assert len(flagged) == 1 and len(ext) >= 3  # once, in the first packet of one scan [k]
    assert [p.flags for p in flagged[0][1:]] == [0] * 5

    client.send(Command.SIM_LRF_ENABLE, 0)
    sent = sim.wait_until(lambda s: s.laser_mode == 0, 30).laser_scans
    client.sips(3)
    assert sim.snapshot().laser_scans == sent  # no scan after "off"


def test_laser_is_off_at_each_session_start_and_absent_without_a_laser(
    make_sim: MakeSim, connect: Connect
) -> None:
    sim = make_sim(time_scale=10.0)
    client = connect(sim)
    client.open_session()
    client.send(Command.ADSEL, 2)
    client.expect(PacketType.SIM_LASER)
    client.send(Command.CLOSE, 1)
    sim.wait_until(lambda s: not s.session_open, 30)
    client.open_session()
    assert not [p for p in client.collect(0.4) if p[0] in LASER_TYPES]

    bare = make_sim(time_scale=10.0, laser=None)  # a robot without a laser: 35 is ADSEL
    client = connect(bare)
    client.open_session()
    client.send(Command.ADSEL, 2)
    bare.wait_until(lambda s: s.commands["ADSEL"] == 1, 30)
    assert client.latest_sip()["io"]["anport"] == 2
    assert not [p for p in client.collect(0.3) if p[0] in LASER_TYPES]


def test_no_return_is_the_models_maximum_range(make_sim: MakeSim, connect: Connect) -> None:
    spec = LaserSpec(name="tim510", max_range=4.0, no_return_mm=4000, noise=0.0)
    sim = make_sim(world=World.from_segments([(3.0, -0.5, 3.0, 0.5)]), time_scale=10.0,
                   laser=spec)  # fmt: skip
    client = connect(sim)
    client.open_session()
    client.send(Command.SIM_LRF_ENABLE, 2)
    client.expect(PacketType.SIM_LASER)
    client.sip()
    scan = scans(client.collect(0.3))[0]
    r = ranges_of(scan)
    assert r[90] == 3000 and r[0] == r[-1] == 4000  # wall dead ahead; nothing at the sides
    assert sim.snapshot().laser_ranges[0] == math.inf
    assert LMS200.no_return_mm == arcos.LASER_NO_RETURN_MM == 32767
