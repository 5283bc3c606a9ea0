"""What robocli writes for a viewer, checked as Foxglove and Lichtblick take it: every JSON
schema of every channel, in files and live, inside the subset those viewers read (one type
string per field, no union, no null: Lichtblick refused five channels over
``["number","null"]``), every message valid under its schema (jsonschema), and every message
on a Foxglove well-known schema valid under Foxglove's own (``@foxglove/schemas`` 2.1.0,
vendored in tests/data/foxglove_schemas)."""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from robocli.devices.arm import Arm
from robocli.devices.hub.client import Hub
from robocli.devices.laser import Laser
from robocli.devices.pioneer import Pioneer
from robocli.hub_server import HubServer
from robocli.io.record import Recorder, RecordingError, pull_hub
from robocli.io.record.links import json_text
from robocli.io.record.reader import raw_frame
from robocli.io.schemas import FOXGLOVE, SCHEMAS
from robocli.sim.hokuyo.server import HokuyoSim
from tests.io.readback import FOXGLOVE_SCHEMAS, by_topic, decoded, foxglove_subset, viewer_checked
from tests.waiting import wait_for

#: hub sensors and their settings: every kind of channel a hub gives
HUB = {"imu": {"rate": 100}, "adc": {"rate": 200}, "battery": {"rate": 10},
       "gps": {"rate": 5}, "sysinfo": {"rate": 5}, "laser": {"rate": 10},
       "camera": {"rate": 10, "resolution": "160x120"},
       "stereo": {"rate": 5, "resolution": "160x120"},
       "depth": {"rate": 5, "resolution": "160x120"}}  # fmt: skip
#: the decoded channels of a Pioneer with its laser, an arm with feedback, that hub, a laser
TOPICS = {
    "/pioneer/pose", "/pioneer/tf", "/pioneer/sonar", "/pioneer/laser", "/pioneer/state",
    "/arm/joint_states", "/arm/joint_feedback", "/arm/tcp", "/arm/tf", "/arm/status",
    "/hub/imu", "/hub/adc", "/hub/battery", "/hub/gps", "/hub/sysinfo", "/hub/laser",
    "/hub/camera", "/hub/stereo/left", "/hub/stereo/right", "/hub/depth/rgb",
    "/hub/depth/image",
}  # fmt: skip


def test_every_schema_is_in_the_subset_foxglove_reads() -> None:
    for name, schema in SCHEMAS.items():
        foxglove_subset(schema, name)
        # what robocli can leave out is never required (a viewer's plot shows a gap)
    assert "robot_time" not in SCHEMAS["robocli.JointState"]["required"]
    assert "drives_powered" not in SCHEMAS["robocli.arm.Status"]["required"]
    # and each Foxglove schema robocli writes is one Foxglove ships
    assert set(FOXGLOVE) <= set(FOXGLOVE_SCHEMAS)


def test_foxglove_subset_refuses_what_lichtblick_refused() -> None:
    union = {"type": "object", "properties": {
        "sonar": {"type": "array", "items": {"type": ["number", "null"]}}}}  # fmt: skip
    with pytest.raises(AssertionError, match="one type string"):
        foxglove_subset(union)
    with pytest.raises(AssertionError, match="type 'null'"):
        foxglove_subset({"type": "object", "properties": {"t": {"type": "null"}}})
    with pytest.raises(AssertionError, match="anyOf"):
        foxglove_subset({"type": "object", "properties": {
            "x": {"type": "number", "anyOf": [{"type": "number"}]}}})  # fmt: skip
    with pytest.raises(AssertionError, match="not one of"):  # no array of arrays
        foxglove_subset(
            {
                "type": "object",
                "properties": {
                    "m": {"type": "array", "items": {"type": "array", "items": {"type": "number"}}}
                },
            }
        )
    with pytest.raises(AssertionError, match="contentEncoding"):  # base64 or nothing
        foxglove_subset({"type": "object", "properties": {
            "b": {"type": "string", "contentEncoding": "base16"}}})  # fmt: skip


def test_what_robocli_does_not_know_is_left_out_not_null() -> None:
    """A NaN or an infinity (no reading) leaves its field out, and a list holding one
    (a hole would shift the indexes after it); a viewer's plot then shows a gap."""
    nan, inf = float("nan"), float("inf")
    text = json_text({"x": 1.5, "battery": nan, "sonar": [1.0, inf], "cpu": {"user": -inf,
                      "sys": 2.0}, "flags": [True], "name": "a"})  # fmt: skip
    assert json.loads(text) == {"x": 1.5, "cpu": {"sys": 2.0}, "flags": [True], "name": "a"}
    status = {"timestamp": {"sec": 1, "nsec": 0}, "mode": "AUTO", "error_code": 0}
    viewer_checked("robocli.arm.Status", SCHEMAS["robocli.arm.Status"], status)  # flags unknown
    joints = {
        "timestamp": {"sec": 1, "nsec": 0},
        "name": ["joint_1"],
        "position": [0.0],
        "velocity": [],
        "effort": [],
        "source": "joint_position",
    }  # no robot_time
    viewer_checked("robocli.JointState", SCHEMAS["robocli.JointState"], joints)


def test_a_malformed_raw_frame_is_a_typed_error() -> None:
    for data in (b"{}", b"not json", b'{"data": "not base64!"}', b'{"data": 3}'):
        with pytest.raises(RecordingError, match="raw frame"):
            raw_frame("json", data)
    assert raw_frame("robocli.raw", b"\xfa\xfb") == b"\xfa\xfb"  # older recordings: as is


@pytest.fixture
def laser_url() -> Iterator[str]:
    with HokuyoSim("utm-30lx", time_scale=2.0) as sim:
        yield sim.serve_tcp("127.0.0.1", 0)


def _subscribe_all(hub: Hub) -> None:
    for name, settings in HUB.items():
        hub.subscribe(name, **settings)


def test_every_channel_of_a_recording_loads_in_a_viewer(
        pioneer_url: str, abb: tuple[int, int], hub_server: HubServer, laser_url: str,
        tmp_path: Path) -> None:  # fmt: skip
    path = tmp_path / "all.mcap"
    with Recorder(path) as rec:
        with Pioneer.connect(pioneer_url, laser=True) as robot, \
                Arm.connect("127.0.0.1", *abb, motion=False) as arm, \
                Hub.connect(f"127.0.0.1:{hub_server.port}") as hub, \
                Laser.connect(laser_url) as laser:  # fmt: skip
            for device in (robot, arm, hub, laser):
                rec.add(device)
            _subscribe_all(hub)
            got: set[str] = set()

            def pulled() -> bool:
                for name in HUB:
                    if len(hub.read(name)):
                        got.add(name)
                return got == set(HUB)

            wait_for(pulled, what="a sample of every hub sensor")
            robot.sim.wait_for_laser(30.0)
            list(laser.scans(2))
            arm.wait_for_state(30.0)
    topics = by_topic(path)
    assert TOPICS | {"/laser/scan"} <= set(topics), sorted(TOPICS - set(topics))
    raw = {t for t in topics if "/raw/" in t}  # every link's frames, in a viewer too
    assert raw >= {"/pioneer/raw/tx", "/pioneer/raw/rx", "/hub/raw/tx", "/hub/raw/rx",
                   "/laser/raw/tx", "/laser/raw/rx", "/arm/raw/state/rx"}  # fmt: skip
    known: list[bool] = []
    for topic, items in topics.items():
        schema, channel, _ = items[0]
        assert schema is not None, f"{topic}: no schema"
        assert schema.encoding == "jsonschema", topic
        foxglove_subset(json.loads(schema.data), f"{topic} ({schema.name})")
        assert channel.message_encoding == "json", topic
        for item in items:
            decoded(item)  # valid under its schema and, if Foxglove's, under theirs
    for item in topics["/pioneer/state"]:
        state = decoded(item)
        assert len(state["sonar"]) == len(state["sonar_known"]) == 16
        known.extend(state["sonar_known"])
    assert True in known


def test_every_live_channel_loads_in_a_viewer(pioneer_url: str, abb: tuple[int, int],
                                              hub_server: HubServer) -> None:  # fmt: skip
    pytest.importorskip("websockets")
    from robocli.io.record.live import LiveView
    from tests.io.foxglove_client import FoxgloveClient

    stop = threading.Event()
    with LiveView(port=0) as view, Pioneer.connect(pioneer_url, laser=True) as robot, \
            Arm.connect("127.0.0.1", *abb, motion=False) as arm, \
            Hub.connect(f"127.0.0.1:{hub_server.port}") as hub:  # fmt: skip
        for device in (robot, arm, hub):
            view.add(device)
        _subscribe_all(hub)
        puller = threading.Thread(target=pull_hub, args=(hub, list(HUB), 20, stop.is_set))
        puller.start()
        try:
            with FoxgloveClient(view.url) as client:
                channels = client.wait_for_topics(TOPICS)
                subs: dict[str, Any] = {}
                for topic, channel in channels.items():
                    foxglove_subset(channel.schema, f"{topic} ({channel.schema_name})")
                    subs[topic] = client.subscribe(channel)
                for topic, sub in subs.items():  # each checked as a viewer takes it
                    try:
                        assert client.messages(sub, 1), topic
                    except (TimeoutError, AssertionError) as exc:
                        srv = view.server
                        raise AssertionError(
                            f"{topic}: {exc}; view dropped {view.dropped}, errors {view.errors},"
                            f" messages {view.messages}; server dropped {srv.dropped}, "
                            f"slow {srv.slow_disconnected}, peak queued {srv.peak_queued}"
                        ) from None
        finally:
            stop.set()
            puller.join(30)
