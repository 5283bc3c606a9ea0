"""Recording an iRobot Create 2 (its sensor stream: pose, bumpers, battery) against the
built-in simulator over a real socket; the file is read back with the ``mcap`` package's own
reader and every JSON message is checked against the schema its channel names."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from robocli.devices.create import STREAMED, Create, CreateState
from robocli.errors import InvalidArgument
from robocli.io.record import Recorder
from robocli.protocols import create_oi as oi
from robocli.protocols.create_oi import Op
from robocli.sim.create import CreateSim
from robocli.sim.world import World
from tests.commands.helpers import run
from tests.io.readback import by_topic, decoded, frame_of

TOPICS = {
    "/create/pose": "foxglove.PoseInFrame",
    "/create/tf": "foxglove.FrameTransform",
    "/create/state": "robocli.create.State",
}
WAIT = 10.0


def test_create_pose_bumpers_and_battery_are_recorded(tmp_path: Path) -> None:
    """A Create driven in full mode into a wall 0.5 m ahead (a toolkit's commands, sent on
    the recorded link): the recorded poses follow the client's odometry and the simulator's,
    the bump shows in the state, the battery in SI units; the raw channels hold the OI's
    bytes both ways."""
    world = World.from_segments([(0.67, -2.0, 0.67, 2.0)], name="wall")
    path = tmp_path / "create.mcap"
    with CreateSim(world=world, start_pose=(0.0, 0.0, 0.0), time_scale=2.0) as sim:
        url = sim.serve_tcp()
        with Recorder(path) as rec:
            listener = rec.listener("create", "create-oi", url=url)
            with Create.connect(url, listeners=[listener]) as robot:
                assert rec.add(robot, listener.name) == "create"
                robot.session.send(oi.build_command(Op.FULL))
                robot.session.send(oi.build_command(Op.DRIVE_DIRECT, right=200, left=200))
                end = time_bound(robot, lambda s: s.bump_left and s.bump_right)
                truth = sim.wait_until(lambda s: s.left == 0.0, WAIT)  # stalled at the wall
                last = time_bound(robot, lambda s: s.frames > end.frames + 2)
            assert rec.stats.dropped == 0
    topics = by_topic(path)
    for topic, schema in TOPICS.items():
        assert topic in topics and all(item[0].name == schema for item in topics[topic])
    states = [decoded(item) for item in topics["/create/state"]]
    poses = [decoded(item) for item in topics["/create/pose"]]
    assert len(states) == len(poses) >= last.frames
    assert {p["frame_id"] for p in poses} == {"create/odom"}
    final = states[-1]
    assert abs(final["x"] - last.x) < 1e-9 and abs(final["x"] - truth.odom_x) < 0.002
    assert final["bump_left"] and final["bump_right"] and final["mode"] == 3
    assert not states[0]["bump_left"] and states[0]["mode"] == 1
    assert math.isclose(final["capacity"], 2.696) and 13.0 < final["voltage"] <= 16.0
    assert final["current"] < 0
    tx = [frame_of(item) for item in topics["/create/raw/tx"]]
    assert tx[:2] == [bytes([Op.START]), oi.build_command(Op.STREAM, packets=list(STREAMED))]
    assert tx[-1] == oi.build_command(Op.PAUSE_RESUME_STREAM, resume=0)  # closing
    rx = [frame_of(item) for item in topics["/create/raw/rx"]]
    assert len(rx) == len(states) and all(oi.parse_stream(f) for f in rx)


def time_bound(robot: Create, pred: Callable[[CreateState], bool]) -> CreateState:
    """The first state streamed within WAIT s that satisfies ``pred``."""
    end = time.monotonic() + WAIT
    while time.monotonic() < end:
        state = robot.wait_for_state(WAIT)
        if pred(state):
            return state
    raise AssertionError("condition not met")


def test_record_create_sim_from_the_cli(tmp_path: Path) -> None:
    out = tmp_path / "c.mcap"
    proc = run("record", "--create", "sim", "-o", str(out), "--count", "40")
    assert proc.returncode == 0, proc.stderr
    topics = by_topic(out)
    assert len(topics["/create/state"]) >= 10
    assert decoded(topics["/create/state"][-1])["mode"] == 1  # passive: nothing moves


def test_a_create_added_without_a_listener_is_recorded_from_then_on(tmp_path: Path) -> None:
    path = tmp_path / "late.mcap"
    with CreateSim(time_scale=2.0) as sim, Recorder(path) as rec:
        with Create.connect(sim.serve_tcp()) as robot:
            assert rec.add(robot) == "create"
            with pytest.raises(InvalidArgument, match="recorded already"):
                rec.add(robot, "create")
            seen = robot.wait_for_state().frames
            time_bound(robot, lambda s: s.frames > seen + 5)
    topics = by_topic(path)
    assert len(topics["/create/state"]) >= 5
    assert topics["/create/raw/tx"]  # the closing pause at least
