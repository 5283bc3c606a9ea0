"""SIMSTAT (237 -> 0x62), SIM_SET_POSE, SIM_RESET and SETO in the built-in simulator, checked
against the recorded AMRISim traces i (SIMSTAT) and j (SETO timing), over real sockets."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import pytest

from robocli import Pioneer
from robocli.io.capture import read_capture
from robocli.protocols import arcos
from robocli.protocols.arcos import Command, PacketType
from robocli.sim.pioneer.server import PioneerSim
from robocli.sim.pioneer.simext import lat_lon
from robocli.sim.world import World
from tests import paths

if TYPE_CHECKING:
    from tests.sim.conftest import RawClient

DATA = paths.DATA / "arcos"
MakeSim = Callable[..., PioneerSim]
Connect = Callable[[PioneerSim], "RawClient"]
BOSTON = (42.3601, -71.0589, 10.0)  #: the OriginLatLongAlt of the traces' map


def recorded(stem: str, direction: str) -> list[bytes]:
    return [
        arcos.unframe(f.frame)
        for f in read_capture(DATA / f"{stem}.jsonl")
        if f.direction == direction
    ]


def types_until_sips(client: RawClient, n: int) -> list[int]:
    """Packet types received until the ``n``-th SIP (included)."""
    out: list[int] = []
    while out.count(PacketType.SIP) < n:
        p = client.next(5.0)
        assert p is not None
        out.append(p[0])
    return out


def types_after_sip(client: RawClient, k: int, n: int) -> list[int]:
    """The packet types the client received after the ``k``-th SIP of its link, until ``n``
    SIPs more have come. SIPs are numbered as the simulator counts them (``sips_sent``): it
    sends them all, in order, on this one link, so a snapshot's count places the client's
    stream at the instant of the snapshot, however late the client reads it."""
    while sum(p[0] == PacketType.SIP for _, p in client.log) < k + n:
        assert client.next(5.0) is not None
    order = [p[0] for _, p in client.log]
    sips = [i for i, t in enumerate(order) if t == PacketType.SIP]
    return order[sips[k - 1] + 1 : sips[k + n - 1] + 1]


def test_simstat_replies_field_by_field_like_trace_i(make_sim: MakeSim, connect: Connect) -> None:
    theirs = [arcos.decode_simstat(p[1:]) for p in recorded("i_simstat", "rx") if p[0] == 0x62]
    assert len(theirs) > 10
    sim = make_sim(world=World.empty(), time_scale=10.0, georef=BOSTON)
    client = connect(sim)
    client.open_session()
    client.flush()
    client.send(Command.SIM_STAT, 1)
    client.expect(PacketType.SIM_STAT, 10.0)
    types_until_sips(client, 2)  # two cycles more: no second reply
    order = [p[0] for _, p in client.log]
    assert order.count(PacketType.SIM_STAT) == 1
    assert order[order.index(PacketType.SIM_STAT) - 1] == PacketType.SIP  # after a SIP [i]
    got = [p for p in client.log if p[1][0] == PacketType.SIM_STAT][-1][1]
    assert len(got) - 1 == 56
    ours = arcos.decode_simstat(got[1:])
    origin = theirs[0]
    for key in ("str1", "str2", "flags", "sim_interval", "x", "y", "z", "th", "gps_dop"):
        assert ours[key] == origin[key], key
    assert ours["real_interval"] == 10 and ours["flags"] == 6  # 100 ms / time_scale 10
    # no AMRISim bias: the origin reads as the map's georeference
    assert (ours["latitude"], ours["longitude"], ours["altitude"]) == (423601000, -710589000, 1000)

    # SIM_SET_POSE moves the true pose (SIMSTAT), not the odometry (SIP); GPS follows [i]
    client.send_raw(next(arcos.frame(p) for p in recorded("i_simstat", "tx") if p[0] == 224))
    client.send(Command.SIM_STAT, 1)
    moved = arcos.decode_simstat(client.expect(PacketType.SIM_STAT)[1:])
    theirs_moved = next(s for s in theirs if s["x"] == 1000)
    for key in ("x", "y", "z", "th"):
        assert moved[key] == theirs_moved[key], key
    assert moved["longitude"] - ours["longitude"] == pytest.approx(
        theirs_moved["longitude"] - origin["longitude"], abs=1
    )  # +1000 mm east: +122 x 1e-7 deg
    assert moved["latitude"] - ours["latitude"] == pytest.approx(
        theirs_moved["latitude"] - origin["latitude"], abs=1
    )  # -500 mm north: -45 x 1e-7 deg
    assert client.latest_sip()["x"] == 0
    lat, lon = lat_lon(BOSTON, 1.0, -0.5)
    assert (round(lat * 1e7), round(lon * 1e7)) == (moved["latitude"], moved["longitude"])


def test_simstat_modes_none_two_and_zero(make_sim: MakeSim, connect: Connect) -> None:
    sim = make_sim(time_scale=10.0)  # no georeference
    client = connect(sim)
    client.open_session()
    client.flush()
    client.send_raw(arcos.frame(bytes((Command.SIM_STAT,))))  # no argument = 0: no reply [i]
    assert PacketType.SIM_STAT not in types_until_sips(client, 3)

    sent_at = sim.snapshot().sips_sent
    client.send(Command.SIM_STAT, 2)
    taken_by = sim.wait_until(lambda s: s.simstat_mode == 2, 30).sips_sent
    # from the second SIP after the request, a 0x62 right before every SIP [i]: the request
    # was taken between SIPs sent_at and taken_by, however long the machine delayed it
    assert types_after_sip(client, taken_by + 1, 4) == [PacketType.SIM_STAT, PacketType.SIP] * 4
    order = [p[0] for _, p in client.log]
    sips_before = order[: order.index(PacketType.SIM_STAT)].count(PacketType.SIP)
    assert sent_at + 1 <= sips_before <= taken_by + 1
    stat = arcos.decode_simstat([p for _, p in client.log if p[0] == 0x62][-1][1:])
    assert stat["flags"] == arcos.SIMSTAT_FLAG_ODOM_ERROR  # odometry-error fields, no GPS
    assert (stat["latitude"], stat["longitude"], stat["altitude"], stat["gps_dop"]) == (
        0, 0, 0, -1
    )  # fmt: skip
    assert sim.snapshot().simstat_mode == 2

    client.send(Command.SIM_STAT, 0)
    taken_by = sim.wait_until(lambda s: s.simstat_mode == 0, 30).sips_sent
    # one more can come, before the next SIP [i]; none after it
    assert PacketType.SIM_STAT not in types_after_sip(client, taken_by + 1, 3)


def test_odometry_error_fields_report_the_modelled_noise(
    make_sim: MakeSim, connect: Connect
) -> None:
    sim = make_sim(world=World.empty(), time_scale=10.0, odom_noise=0.005, seed=3)
    client = connect(sim)
    client.open_session(enable=True)
    client.send(Command.VEL, 300)
    sim.wait_until(lambda s: s.trans_vel > 0.1, 30)
    client.send(Command.SIM_STAT, 1)
    stat = arcos.decode_simstat(client.expect(PacketType.SIM_STAT)[1:])
    assert stat["odom_error_x"] != 0 and abs(stat["odom_error_x"]) < 0.05 * 1e10
    assert stat["odom_error_x"] == stat["odom_error_y"]  # one distance error in this model
    assert abs(stat["odom_error_th"]) < 0.05 * math.degrees(1) * 1e7


def test_sim_reset_shows_in_the_second_sip(make_sim: MakeSim, connect: Connect) -> None:
    sim = make_sim(world=World.empty(), time_scale=10.0, start_pose=(1.0, 2.0, 0.0))
    client = connect(sim)
    client.open_session(enable=True)
    client.send(Command.VEL, 300)
    sim.wait_until(lambda s: s.odom_x > 0.3, 30)
    client.send(Command.VEL, 0)
    sim.wait_until(lambda s: s.trans_vel == 0.0, 30)
    client.latest_sip()
    client.send(Command.SIM_RESET)
    # [i]: the SIP after the command still has the old pose, the one after it the reset one.
    # A loaded machine can run one more SIP cycle between the send and the simulator reading
    # the command: then the reset shows one SIP later, never earlier, and stays.
    sips = [(p["x"], p["y"], p["th"]) for p in client.sips(4)]
    assert sips[0][0] > 0 and (0, 0, 0) in sips[1:3], sips
    reset_at = sips.index((0, 0, 0))
    assert all(p == (0, 0, 0) for p in sips[reset_at:]), sips
    s = sim.snapshot()
    assert (s.x, s.y, s.th) == (1.0, 2.0, 0.0)  # back to the start pose


def test_seto_shows_in_the_second_sip_like_trace_j(make_sim: MakeSim, connect: Connect) -> None:
    """Trace j: the SIP right after SETO still has the old counters, the next one the new."""
    sent = recorded("j_seto_timing", "tx")
    with_values = next(p for p in sent if p[0] == Command.SETO and len(p) > 1)
    assert arcos.decode_seto(with_values) == (1000, 500, 90)
    sim = make_sim(world=World.empty(), time_scale=10.0)
    client = connect(sim)
    client.open_session(enable=True)
    client.send(Command.VEL, -300)
    sim.wait_until(lambda s: s.odom_x < -0.2, 30)
    client.send(Command.VEL, 0)
    sim.wait_until(lambda s: s.trans_vel == 0.0, 30)
    old = client.latest_sip()
    client.send(Command.SETO)
    first, second = client.sips(2)
    assert first["x"] == old["x"] > 0x4000  # negative x: old counters still
    assert (second["x"], second["y"], second["th"]) == (0, 0, 0)

    client.send_raw(arcos.frame(with_values))  # 1000 mm, 500 mm, 90 deg [j]
    first, second = client.sips(2)
    assert (first["x"], first["y"]) == (0, 0)
    # AMRISim: x=2061, y=1030, th=1023 (it truncates); we round
    assert second["x"] == pytest.approx(2061, abs=1) and second["y"] == pytest.approx(1030, abs=1)
    assert second["th"] == pytest.approx(1023, abs=1)
    s = sim.snapshot()
    assert (s.odom_x, s.odom_y, s.odom_th) == pytest.approx((1.0, 0.5, math.pi / 2))
    assert s.x < -0.2  # the true pose is unaffected


def test_setv_and_config_stay_within_the_robots_top_speed(
    make_sim: MakeSim, connect: Connect
) -> None:
    """CONFIG's maxima never exceed its tops (the vendor SDK warns on every connect if they
    do); SETV above the top is capped like ARCOS does."""
    sim = make_sim(time_scale=10.0)
    client = connect(sim)
    client.open_session()
    client.send(Command.CONFIG, 1)
    cfg = arcos.parse_config(client.expect(PacketType.CONFIG)[1:])
    assert cfg["transvel_max"] <= cfg["transvel_top"] and cfg["rotvel_max"] <= cfg["rotvel_top"]
    assert cfg["trans_accel"] <= cfg["transacc_top"] and cfg["rot_accel"] <= cfg["rotacc_top"]
    client.send(Command.SETV, 3000)  # what the vendor SDK echoes from AMRISim's CONFIG
    client.send(Command.CONFIG, 1)
    cfg = arcos.parse_config(client.expect(PacketType.CONFIG)[1:])
    assert cfg["transvel_max"] == cfg["transvel_top"] == 2200


def test_client_reset_odometry_reads_zero_although_the_first_sip_is_old(
    make_sim: MakeSim,
) -> None:
    """The +15.9 m bug: a robot at negative x, SETO; the simulator's first SIP after it still
    carries the old (negative, i.e. near 0x7FFF) counters, as AMRISim's; the client's pose
    must read ~0 throughout, never 15.9 m (32768 x 0.485 mm)."""
    sim = make_sim(world=World.empty(), time_scale=10.0)
    assert sim.url is not None
    raw_x: list[int] = []

    def sips(direction: str, payload: bytes, t: float) -> None:
        if direction == "rx" and payload[0] == PacketType.SIP:
            raw_x.append(arcos.decode_sip(payload[1:])["x"])

    with Pioneer.connect(sim.url, listeners=[sips]) as robot:
        robot.enable_motors()
        robot.set_velocity(-0.3, 0.0)
        sim.wait_until(lambda s: s.odom_x < -0.3, timeout=30)
        robot.stop()
        sim.wait_until(lambda s: s.trans_vel == 0.0, timeout=30)
        robot.wait_for_sip()
        assert robot.pose[0] < -0.3
        before = len(raw_x)
        robot.reset_odometry()
        for _ in range(6):
            x, y, _th = robot.wait_for_sip().pose
            assert abs(x) < 0.005 and abs(y) < 0.005
        after = raw_x[before:]
        assert after[0] > 0x4000  # the first SIP after SETO: old negative counters
        assert 0 in after[1:3]  # then the reset
        assert robot.pose == pytest.approx((0.0, 0.0, 0.0), abs=0.005)
