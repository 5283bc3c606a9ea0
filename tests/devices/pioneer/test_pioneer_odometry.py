"""Odometry tracked from counter deltas (issue 7, item 1), against recorded AMRISim traffic
and the built-in simulator."""

from __future__ import annotations

import pytest

from robocli.devices.pioneer import Pioneer
from robocli.devices.pioneer.state import Odometry, sip_essentials
from robocli.io.capture import read_capture
from robocli.protocols import arcos
from robocli.sim.pioneer.server import PioneerSim
from tests import paths

DATA = paths.DATA / "arcos"
SETO = arcos.encode_command(arcos.Command.SETO)


def _signed(v: int) -> int:
    return v - 0x8000 if v >= 0x4000 else v


def test_seto_applied_one_sip_late_gives_zero_not_16_m() -> None:
    """Trace j: AMRISim shows SETO in the second SIP after it, so the first SIP still
    carries the old counters (x = -962 raw = 32806 - 0x8000). The client used to read
    that as +15.9 m."""
    odo = Odometry()
    setos = 0
    after_reset: list[tuple[int, int, int]] = []  # (SIPs since SETO, client x, robot x)
    since = 0
    for f in read_capture(DATA / "j_seto_timing.jsonl"):
        if f.direction == "tx" and f.frame[3] == arcos.Command.SETO:
            setos += 1
            if f.frame != SETO:
                break  # the third SETO carries three arguments, which Pioneer never sends
            odo.expect_reset()
            since = 0
        elif f.direction == "rx" and f.frame[3] & 0xF0 == 0x30:
            x, y, _ = sip_essentials(f.frame[4:-2])
            cx, cy = odo.update(x, y)
            since += 1
            if setos:
                after_reset.append((since, cx, _signed(x & 0x7FFF)))
            assert abs(cx) < 3000 and abs(cy) < 3000  # within 1.5 m: never the 15.9 m jump
    assert setos == 3
    # once the robot shows its reset (from the second SIP on), the client follows it exactly
    assert all(cx == rx for since, cx, rx in after_reset if since >= 2)
    # before that, the client already reads (near) zero, not the old counters
    firsts = [cx for since, cx, _ in after_reset if since == 1]
    assert len(firsts) == 2 and all(abs(cx) <= 50 for cx in firsts)


@pytest.mark.parametrize("raw_x", [32276, 0x7FFF, 1, 100])
def test_counters_at_open_are_read_as_signed(raw_x: int) -> None:
    """A robot whose counters are slightly negative at OPEN starts slightly negative."""
    odo = Odometry()
    x, _ = odo.update(raw_x, 0)
    assert x == _signed(raw_x) and abs(x) < 0x4000


def test_a_reset_read_behind_many_old_sips_still_reads_zero() -> None:
    """A loaded client reads, after its SETO, SIPs that the robot sent before it: the reset
    was looked for in the next 4 SIPs only, so behind a fifth old one it read as a jump back
    over the whole distance (+0.195 m after reversing 0.195 m, on a loaded test run)."""
    odo = Odometry()
    old = 0x8000 - 402  # x = -402 units (-0.195 m)
    odo.update(old, 0, now=10.0)
    odo.expect_reset(now=10.0)
    for _ in range(8):  # read in one burst, 10 ms after the SETO
        assert odo.update(old, 0, now=10.01) == (0, 0)
    assert odo.update(0, 0, now=10.02) == (0, 0)  # the robot's reset
    assert odo.update(20, 0, now=10.03) == (20, 0)  # and its counters from there
    odo.expect_reset(now=20.0)
    for _ in range(8):  # a robot that never resets, long after: its deltas count again
        odo.update(20, 0, now=25.0)
    assert odo.update(5, 0, now=25.1) == (-15, 0)


def test_reset_odometry_against_the_simulator(empty_sim: PioneerSim) -> None:
    assert empty_sim.url is not None
    with Pioneer.connect(empty_sim.url) as robot:
        robot.enable_motors()
        robot.set_velocity(-0.3, 0.0)  # backwards: negative counters
        empty_sim.wait_until(lambda s: s.odom_x < -0.2, timeout=30)
        robot.stop()
        empty_sim.wait_until(lambda s: abs(s.trans_vel) < 1e-6, timeout=30)
        robot.reset_odometry()
        for _ in range(4):
            state = robot.wait_for_sip()
            assert abs(state.x) < 0.01 and abs(state.y) < 0.01
