"""A Hokuyo mounted on a Pioneer (issue 16): the robot model's mount, the transform of a scan
into the robot's and the odometry frame, and a simulated Hokuyo that moves with a simulated
Pioneer in the same world, over real sockets."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from robocli.devices.laser import LaserInfo, MountedLaser, PlacedScan, Scan, scan_points
from robocli.devices.laser.mounted import on_robot
from robocli.devices.laser.scan import make_scan
from robocli.devices.pioneer import Pioneer
from robocli.robots.geometry import Mount
from robocli.robots.pioneer import ROBOT_PARAMS
from robocli.sim.hokuyo import MODELS
from robocli.sim.pioneer.server import PioneerSim
from robocli.sim.world import World


def _info() -> LaserInfo:
    model = MODELS["utm-30lx"]
    pp = dict(line.split(":", 1) for line in model.pp())
    return LaserInfo({"SERI": "X"}, pp)


def _scan(ranges_mm: list[int], steps: list[int]) -> Scan:
    """A whole scan reading error code 0 everywhere but ``ranges_mm`` at ``steps``."""
    info = _info()
    raw = np.zeros(info.amax + 1, dtype=np.int64)
    raw[steps] = ranges_mm
    return make_scan(info, raw=raw, intensities=None, start=0, cluster=1, t=0.0,
                     stamp_ms=0, received=0.0, command="GD", remaining=None)  # fmt: skip


def test_the_p3dx_model_mounts_its_laser_18_mm_ahead() -> None:
    assert ROBOT_PARAMS["p3dx"].laser_mount == Mount(0.018, 0.0, 0.0, flipped=False)
    assert ROBOT_PARAMS["p3dx-sh"].laser_mount == Mount(0.018, 0.0, 0.0)


def test_a_return_1_m_ahead_of_a_robot_at_1_2_heading_90_deg() -> None:
    info = _info()
    scan = _scan([1000], [info.afrt])  # straight ahead
    mount = ROBOT_PARAMS["p3dx"].laser_mount
    odom = scan_points(scan, (1.0, 2.0, math.pi / 2), mount)
    assert odom[info.afrt] == pytest.approx([1.0, 3.018], abs=1e-9)
    robot = scan_points(scan, mount=mount)
    assert robot[info.afrt] == pytest.approx([1.018, 0.0], abs=1e-9)
    assert np.isnan(odom[0]).all()  # step 0 carries an error code: no point
    placed = PlacedScan(scan, (1.0, 2.0, math.pi / 2), mount)
    data = placed.as_dict()
    assert data["points_odom"][info.afrt] == [1.0, 3.018]
    assert data["points_robot"][info.afrt] == [1.018, 0.0]
    assert data["points_odom"][0] is None and data["ranges"][0] is None
    assert data["mount"] == {"x": 0.018, "y": 0.0, "th": 0.0, "flipped": False}


def test_a_flipped_or_turned_mount_turns_the_points() -> None:
    info = _info()
    left = info.afrt + info.ares // 4  # +90 deg on the sensor
    scan = _scan([2000], [left])
    turned = scan_points(scan, mount=Mount(0.1, 0.0, math.pi / 2))
    assert turned[left] == pytest.approx([0.1 - 2.0, 0.0], abs=1e-9)  # looking backwards
    flipped = scan_points(scan, mount=Mount(flipped=True))
    assert flipped[left] == pytest.approx([0.0, -2.0], abs=1e-9)  # its left is our right


def test_a_simulated_hokuyo_moves_with_the_simulated_pioneer_in_one_world() -> None:
    """Robot at (1, 2) heading +y in a world with a wall at y = 4: the laser (18 mm ahead)
    reads 1.982 m straight ahead, which is 2 m ahead in the odometry frame; after the robot
    drives forward, the range shrinks by what it drove and the wall stays where it was."""
    world = World.from_segments([(-5.0, 4.0, 5.0, 4.0)], start=(1.0, 2.0, math.pi / 2))
    with PioneerSim(world=world, time_scale=2.0) as sim, \
            Pioneer.connect(sim.serve_tcp("127.0.0.1", 0)) as robot, \
            on_robot("sim", robot, world=world) as laser:  # fmt: skip
        mounted = MountedLaser(laser, robot)
        assert mounted.mount == Mount(0.018, 0.0, 0.0)
        ahead = laser.info.afrt if laser.info else 0
        first = mounted.place(laser.scan())
        assert first.scan.ranges[ahead] == pytest.approx(1.982, abs=0.0015)
        assert first.odom_points[ahead] == pytest.approx([2.0, 0.0], abs=0.0015)
        robot.enable_motors()
        robot.set_velocity(0.3, 0.0)
        deadline = time.monotonic() + 30
        while robot.pose[0] < 0.5:
            assert time.monotonic() < deadline, robot.pose
            robot.wait_for_sip(5)
        robot.stop()
        deadline = time.monotonic() + 30
        while robot.state.v != 0.0:
            assert time.monotonic() < deadline
            robot.wait_for_sip(5)
        robot.wait_for_sip(5)
        robot.wait_for_sip(5)  # the follower has placed the sensor at this pose
        laser.start()
        later = mounted.wait(10.0)
        laser.stop()
        mounted.close()
        assert later.pose[0] > 0.5
        assert later.scan.ranges[ahead] == pytest.approx(1.982 - later.pose[0], abs=0.01)
        assert later.odom_points[ahead] == pytest.approx([2.0, 0.0], abs=0.01)
