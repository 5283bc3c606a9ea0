"""Robot models in recordings and live views: each robot's URDF on ``/NAME/robot_description``
(and the first one's on ``/robot_description``, where Foxglove's and Lichtblick's 3D panel
loads a robot from: schema ``std_msgs/String``), read back with the ``mcap`` package's own
reader and parsed by yourdfpy; the frames the recording moves are the URDF's links, and an
arm's transforms are the URDF's joints at the recorded joint values. A live view keeps the
model for a client that subscribes after it was sent."""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from robocli.devices.arm import Arm
from robocli.devices.pioneer import Pioneer
from robocli.io.record import Recorder
from robocli.kinematics import fk
from robocli.robots.urdf import urdf
from tests.io.readback import by_topic, decoded
from tests.waiting import wait_for

yourdfpy = pytest.importorskip("yourdfpy")
pytest.importorskip("mcap")


def parse(text: str) -> Any:
    return yourdfpy.URDF.load(io.StringIO(text), build_scene_graph=True, load_meshes=False)


def matrix(t: dict[str, Any]) -> Any:
    x, y, z, w = (t["rotation"][k] for k in "xyzw")
    m = np.eye(4)
    m[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]  # fmt: skip
    m[:3, 3] = [t["translation"][k] for k in "xyz"]
    return m


def test_a_recording_carries_each_robots_model_and_moves_its_links(
        pioneer_url: str, abb: tuple[int, int], tmp_path: Path) -> None:  # fmt: skip
    path = tmp_path / "models.mcap"
    with Recorder(path) as rec, Pioneer.connect(pioneer_url) as robot, \
            Arm.connect("127.0.0.1", *abb) as arm:  # fmt: skip
        assert rec.add(robot) == "pioneer" and rec.add(arm) == "arm"
        robot.enable_motors()
        robot.set_velocity(0.2, 0.3)
        arm.move_to(np.radians([20, 10, 5, 30, 30, 10]), duration=0.3)
        arm.wait_until_idle(20)
        wait_for(lambda: robot.wait_for_sip().x > 0.01, what="the Pioneer moving")
    topics = by_topic(path)
    models = {}
    for topic in ("/robot_description", "/pioneer/robot_description", "/arm/robot_description"):
        (item,) = topics[topic]  # written once
        schema, channel, _ = item
        assert schema.name == "std_msgs/String" and channel.metadata == {"latched": "true"}
        models[topic] = decoded(item)["data"]
    assert models["/robot_description"] == models["/pioneer/robot_description"] \
        == urdf("p3dx", prefix="pioneer/")  # fmt: skip
    assert models["/arm/robot_description"] == urdf("irb120", prefix="arm/")
    # the Pioneer: its transform moves the URDF's root, its scans are in its frames
    pioneer = parse(models["/pioneer/robot_description"])
    tf = decoded(topics["/pioneer/tf"][-1])
    assert tf["child_frame_id"] == pioneer.base_link == "pioneer/base_link"
    assert decoded(topics["/pioneer/sonar"][-1])["frame_id"] in pioneer.link_map
    # the arm: each transform is the URDF's joint at the recorded joint values
    arm_model = parse(models["/arm/robot_description"])
    q = decoded(topics["/arm/joint_feedback"][-1])["position"]
    arm_model.update_cfg(q)
    transforms = decoded(topics["/arm/tf"][-1])["transforms"]
    chain = np.eye(4)
    for t in transforms:
        assert t["parent_frame_id"] in arm_model.link_map
        want = arm_model.get_transform(t["child_frame_id"], t["parent_frame_id"])
        assert matrix(t) == pytest.approx(want, abs=1e-9)
        chain = chain @ want
    flange = chain @ arm_model.get_transform("arm/flange", "arm/link_6")
    assert flange[:3, 3] == pytest.approx(fk(arm.robot, q)[0][:3, 3], abs=1e-9)
    tcp = decoded(topics["/arm/tcp"][-1])["pose"]["position"]
    assert [tcp[k] for k in "xyz"] == pytest.approx(flange[:3, 3], abs=1e-9)


def test_a_live_view_gives_the_model_to_a_client_that_comes_later(pioneer_url: str) -> None:
    pytest.importorskip("websockets")
    from robocli.io.record.live import LiveView
    from tests.io.foxglove_client import FoxgloveClient

    with LiveView(port=0) as view, Pioneer.connect(pioneer_url) as robot:
        view.add(robot)
        wait_for(lambda: view.messages >= 10, what="messages sent (the model first)")
        with FoxgloveClient(view.url) as client:  # connects after the model was sent
            channels = client.wait_for_topics({"/robot_description", "/pioneer/pose"})
            channel = channels["/robot_description"]
            assert channel.schema_name == "std_msgs/String"
            ((_, msg),) = client.messages(client.subscribe(channel), 1)
            assert parse(msg["data"]).base_link == "pioneer/base_link"
            assert msg["data"] == urdf("p3dx", prefix="pioneer/")
            # and a second subscription of the same client gets it again
            ((_, again),) = client.messages(client.subscribe(channel), 1)
            assert json.dumps(again) == json.dumps(msg)
