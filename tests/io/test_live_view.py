"""The live view (``--foxglove``): a real WebSocket client speaking the Foxglove protocol
connects to the server fed by the simulators, sees the advertised channels and their
schemas, subscribes, and decodes the binary message frames with the advertised schema."""

from __future__ import annotations

import math
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

pytest.importorskip("websockets")

from robocli.devices.arm import Arm
from robocli.devices.hub.client import Hub
from robocli.devices.pioneer import Pioneer
from robocli.hub_server import HubServer
from robocli.io.record import Recorder, pull_hub
from robocli.io.record.live import LiveView
from tests.commands.helpers import one_line_error, run, running
from tests.io.foxglove_client import SUBPROTOCOLS, FoxgloveClient
from tests.io.readback import by_topic, decoded
from tests.waiting import wait_for


def test_a_pioneer_live(pioneer_url: str) -> None:
    with LiveView(port=0) as view, Pioneer.connect(pioneer_url, laser=True) as robot:
        assert view.url == f"ws://127.0.0.1:{view.port}" and view.port > 0
        assert view.add(robot) == "pioneer"
        robot.enable_motors()
        robot.set_velocity(0.3, 0.2)
        with FoxgloveClient(view.url) as client:
            assert client.ws.subprotocol in SUBPROTOCOLS
            assert client.server_info["name"] == "robocli"
            channels = client.wait_for_topics({"/pioneer/pose", "/pioneer/tf", "/pioneer/sonar",
                                               "/pioneer/laser", "/pioneer/state"})  # fmt: skip
            assert not any("/raw/" in t for t in channels)  # raw bytes are not served
            pose = channels["/pioneer/pose"]
            assert (pose.encoding, pose.schema_name, pose.schema_encoding) == (
                "json",
                "foxglove.PoseInFrame",
                "jsonschema",
            )
            assert channels["/pioneer/tf"].schema_name == "foxglove.FrameTransform"
            assert channels["/pioneer/laser"].schema_name == "foxglove.LaserScan"
            got = client.messages(client.subscribe(pose), 5)
            before = time.time_ns()
            for log_ns, msg in got:
                assert msg["frame_id"] == "pioneer/odom"
                q = msg["pose"]["orientation"]
                assert math.isclose(q["z"] ** 2 + q["w"] ** 2, 1.0, rel_tol=1e-9)
                assert before - 60e9 < log_ns <= before  # host receive time, Unix epoch ns
            assert [t for t, _ in got] == sorted(t for t, _ in got)
            xs = [m["pose"]["position"]["x"] for _, m in got]
            assert xs[-1] != xs[0]  # driving: the poses move
            laser = client.messages(client.subscribe(channels["/pioneer/laser"]), 2)
            assert len(laser[0][1]["ranges"]) == 181


def test_an_arm_and_a_hub_live(abb: tuple[int, int], hub_server: HubServer) -> None:
    motion, state = abb
    with LiveView(port=0) as view, Arm.connect("127.0.0.1", motion, state, motion=False) as arm, \
            Hub.connect("127.0.0.1", hub_server.port) as hub:  # fmt: skip
        view.add(arm)
        view.add(hub)
        hub.subscribe("imu", rate=100)
        with FoxgloveClient(view.url) as client:
            channels = client.wait_for_topics({"/arm/joint_feedback", "/arm/tf"})
            assert channels["/arm/tf"].schema_name == "foxglove.FrameTransforms"
            frames = client.messages(client.subscribe(channels["/arm/tf"]), 3)
            assert len(frames[-1][1]["transforms"]) == 6
            joints = client.messages(client.subscribe(channels["/arm/joint_feedback"]), 3)
            assert joints[-1][1]["name"][0] == "joint_1"
            stop = threading.Event()  # the program pulls; the view shows the replies
            puller = threading.Thread(target=pull_hub, args=(hub, ["imu"], 50, stop.is_set))
            puller.start()
            try:
                imu = client.wait_for_topics({"/hub/imu"})["/hub/imu"]
                assert imu.schema_name == "robocli.Imu"
                got = client.messages(client.subscribe(imu), 5)
            finally:
                stop.set()
                puller.join(30)
            # each sample is sent at its acquisition time, the message's own timestamp
            for log_ns, msg in got:
                assert log_ns == msg["timestamp"]["sec"] * 1_000_000_000 + msg["timestamp"]["nsec"]
            acc = got[-1][1]["linear_acceleration"]
            assert 5 < math.hypot(acc["x"], acc["y"], acc["z"]) < 15  # ~1 g, in m/s^2


def test_a_recorder_mirrors_into_the_live_view(pioneer_url: str, tmp_path: Path) -> None:
    """Decoded once: the messages a client receives are the recording's, byte for byte."""
    path = tmp_path / "mirror.mcap"
    with LiveView(port=0) as view, Recorder(path) as rec:
        rec.mirror(view)
        with Pioneer.connect(pioneer_url) as robot, FoxgloveClient(view.url) as client:
            rec.add(robot)
            pose = client.wait_for_topics({"/pioneer/pose"})["/pioneer/pose"]
            live = client.messages(client.subscribe(pose), 3)
            robot.wait_for_sip()
        assert view.messages >= 3 and view.errors == 0
    recorded = {m.log_time: decoded((s, c, m)) for s, c, m in by_topic(path)["/pioneer/pose"]}
    for log_ns, msg in live:
        assert recorded[log_ns] == msg


def test_record_foxglove_serves_while_recording(tmp_path: Path) -> None:
    path = tmp_path / "live.mcap"
    with running("record", "--pioneer", "sim", "--foxglove", "0", "-d", "600",
                 "-o", str(path)) as proc:  # fmt: skip
        assert proc.stderr is not None
        line = proc.stderr.readline()
        found = re.search(r"live view on (ws://127\.0\.0\.1:\d+)", line)
        assert found, line
        with FoxgloveClient(found[1]) as client:
            channels = client.wait_for_topics({"/pioneer/pose", "/pioneer/laser"})
            assert channels["/pioneer/pose"].schema_name == "foxglove.PoseInFrame"
            got = client.messages(client.subscribe(channels["/pioneer/pose"]), 3)
            assert got[0][1]["frame_id"] == "pioneer/odom"
        proc.terminate()
        assert proc.wait(30) == 130
        err = proc.stderr.read()
    assert "recorded" in err and "Traceback" not in err
    wait_for(lambda: path.stat().st_size > 0, "a non-empty recording")
    assert by_topic(path)["/pioneer/pose"]


def test_a_port_in_use_is_one_line(tmp_path: Path) -> None:
    with LiveView(port=0) as view:
        proc = run("record", "--pioneer", "sim", "--foxglove", str(view.port), "-d", "1",
                   "-o", str(tmp_path / "x.mcap"))  # fmt: skip
        assert "live view" in one_line_error(proc, 3)
    bad = run("record", "--pioneer", "sim", "--foxglove", "70000", "-o", str(tmp_path / "y.mcap"))
    assert bad.returncode == 2


def _live_url(line: str) -> str:
    found = re.search(r"live view on (ws://127\.0\.0\.1:\d+)", line)
    assert found, line
    return found[1]


@pytest.mark.parametrize(
    ("argv", "topic", "schema"),
    [
        (["connect", "pioneer", "sim", "--json"], "/pioneer/pose", "foxglove.PoseInFrame"),
        (["connect", "arm", "sim", "--json"], "/arm/tf", "foxglove.FrameTransforms"),
        (
            ["connect", "pioneer", "sim", "--laser", "sim", "--json"],
            "/laser/scan",
            "foxglove.LaserScan",
        ),
        (
            ["connect", "pioneer", "sim", "--laser", "sim", "--json"],
            "/laser/tf",
            "foxglove.FrameTransform",
        ),
    ],
)
def test_connect_foxglove(argv: list[str], topic: str, schema: str) -> None:
    with running(*argv, "--foxglove", "0") as proc:
        assert proc.stderr is not None and proc.stdout is not None
        with FoxgloveClient(_live_url(proc.stderr.readline())) as client:
            channel = client.wait_for_topics({topic})[topic]
            assert channel.schema_name == schema
            assert len(client.messages(client.subscribe(channel), 3)) == 3
        assert proc.stdout.readline().startswith("{")  # the terminal output goes on
        proc.terminate()
        assert proc.wait(30) == 130


def test_connect_hub_and_serve_foxglove_show_what_the_hub_runs(hub_server: HubServer) -> None:
    """Neither starts a sensor: the view shows the IMU a client makes the hub run."""
    with Hub.connect("127.0.0.1", hub_server.port) as user:
        user.subscribe("imu", rate=100)
        where = f"127.0.0.1:{hub_server.port}"
        with running("connect", "hub", where, "--json", "--window", "0.1",
                     "--foxglove", "0") as proc:  # fmt: skip
            assert proc.stderr is not None
            with FoxgloveClient(_live_url(proc.stderr.readline())) as client:
                imu = client.wait_for_topics({"/hub/imu"})["/hub/imu"]
                assert imu.schema_name == "robocli.Imu"
                assert len(client.messages(client.subscribe(imu), 3)) == 3
            proc.terminate()
            proc.wait(30)
    with running("serve", "--sim", "--port", "0", "--foxglove", "0") as proc:
        assert proc.stderr is not None and proc.stdout is not None
        url = _live_url(proc.stderr.readline())
        served = re.search(r"on tcp://127\.0\.0\.1:(\d+)", proc.stdout.readline())
        assert served, "no hub address"
        log: list[str] = []  # serve's log: a line per change, "gone: LINE" when it no longer holds
        reader = threading.Thread(target=lambda: log.extend(proc.stdout or ()), daemon=True)
        reader.start()
        with FoxgloveClient(url) as client, Hub.connect("127.0.0.1", int(served[1])) as user:
            user.subscribe("adc", rate=100)
            adc = client.wait_for_topics({"/hub/adc"})["/hub/adc"]
            assert adc.schema_name == "robocli.Adc"
            got = client.messages(client.subscribe(adc), 3)
            assert all(len(m["channels"]) == 8 for _, m in got)
            assert "/hub/imu" not in {c.topic for c in client.channels.values()}
            wait_for(lambda: "sensor adc: 100 Hz, 2 subscriber(s)\n" in log, what="the view's")
        # the user left: the view's own subscription does not keep the ADC running
        wait_for(lambda: _holds(log, "sensor adc:") is False, what="the ADC stopped")
        proc.terminate()
        assert proc.wait(30) == 130
        assert "Traceback" not in proc.stderr.read()


def _holds(log: list[str], prefix: str) -> bool:
    """Whether the latest state of ``serve``'s change log has a line starting ``prefix``."""
    now: set[str] = set()
    for line in list(log):
        line = line.rstrip("\n")
        if line.startswith("gone: "):
            now.discard(line[6:])
        else:
            now.add(line)
    return any(line.startswith(prefix) for line in now)


def test_without_websockets_one_line_says_how_to_install() -> None:
    argv = ["connect", "pioneer", "sim", "--once", "--foxglove", "0"]
    code = f"import sys; sys.modules['websockets'] = None; from robocli.cli import main; " \
        f"sys.exit(main({argv!r}))"  # fmt: skip
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60, stdin=subprocess.DEVNULL)  # fmt: skip
    assert "pip install 'robocli-robots[foxglove]'" in one_line_error(proc, 1)
    assert proc.stdout == ""


def test_the_queue_is_bounded_in_items_and_bytes() -> None:
    """Nothing added: no thread drains the queue, so what it holds is what was put."""
    with LiveView(port=0, max_queue=3, max_queue_bytes=1000) as view:
        assert [view.put(print, (), 10) for _ in range(4)] == [True, True, True, False]
        assert view.dropped == 1
    with LiveView(port=0, max_queue_bytes=1000) as view:
        assert view.put(print, (), 600) and not view.put(print, (), 600)
        assert view.dropped == 1
