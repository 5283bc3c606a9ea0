"""robocli's own readers read a ROS 2 bag as they read its JSON recordings (dump --file,
--replay, export, plot, info), ``convert`` turns a recording into a bag that says the same,
and a bag recording killed keeps its chunks."""

from __future__ import annotations

import csv
import math
import os
import signal
from pathlib import Path

import pytest

pytest.importorskip("rosbags")

from robocli.devices.pioneer import Pioneer
from robocli.io.capture import read_capture
from robocli.io.export import arm_log, export
from robocli.io.record import info, recover
from robocli.io.record.replay import RecordedPackets
from robocli.sim.pioneer.replay import PioneerReplay
from tests.commands.helpers import one_line_error, run, running
from tests.ros2.conftest import pioneer_recording
from tests.waiting import wait_for


def _read(path: Path) -> dict[str, list[object]]:
    from rosbags.highlevel import AnyReader

    out: dict[str, list[object]] = {}
    with AnyReader([path]) as reader:
        for conn, _t, raw in reader.messages():
            out.setdefault(conn.topic, []).append(reader.deserialize(raw, conn.msgtype))
    return out


def test_dump_file_and_replay_read_a_bag(bags: dict[str, Path]) -> None:
    path = bags["pioneer"]
    raw = [bytes(m.data) for m in _read(path)["/pioneer/raw/rx"]]  # type: ignore[attr-defined]
    frames = [f.frame for f in read_capture(path, "arcos") if f.direction == "rx"]
    assert frames == raw and len(frames) > 15
    proc = run("dump", "pioneer", "--file", str(path))
    assert proc.returncode == 0 and "SYNC0-reply" in proc.stdout, proc.stderr
    sips = [f[3:-2] for f in raw if f[3] & 0xF0 == 0x30]
    seen: list[bytes] = []
    with PioneerReplay(RecordedPackets(path), speed=4.0) as replay:
        url = replay.serve_tcp("127.0.0.1", 0)
        with Pioneer.connect(
            url,
            listeners=[
                lambda d, p, t: seen.append(p) if d == "rx" and p[0] & 0xF0 == 0x30 else None
            ],
        ):
            wait_for(lambda: len(seen) >= len(sips), what="every recorded SIP")
    assert seen[: len(sips)] == sips


def test_export_plot_and_info_read_a_bag(bags: dict[str, Path], tmp_path: Path) -> None:
    path = bags["pioneer"]
    msgs = _read(path)
    files = {p.name for p in export(path, "csv", tmp_path)}
    assert {"pioneer_odom.csv", "pioneer_laser.csv", "tf.csv"} <= files
    assert not any("raw" in f for f in files)  # raw frames are for dump --file
    with (tmp_path / "pioneer_odom.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [float(r["pose.pose.position.x"]) for r in rows] == [
        m.pose.pose.position.x for m in msgs["/pioneer/odom"]
    ]  # type: ignore[attr-defined]
    first = msgs["/pioneer/odom"][0]
    stamp = first.header.stamp  # type: ignore[attr-defined]
    assert float(rows[0]["t"]) == pytest.approx(stamp.sec + stamp.nanosec / 1e9, abs=1e-6)
    pytest.importorskip("matplotlib")
    out = tmp_path / "drive.png"
    proc = run("plot", str(path), "-o", str(out), "--channel", "/pioneer/odom",
               "--channel", "/pioneer/laser")  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    proc = run("info", str(path))
    assert proc.returncode == 0 and "nav_msgs/msg/Odometry" in proc.stdout


def test_arm_log_reads_an_arm_bag(bags: dict[str, Path]) -> None:
    log = arm_log(bags["arm"])
    assert len(log) >= 20 and log.positions.shape[1] == 6
    assert all(math.isfinite(v) for v in log.positions.ravel())


def test_convert_makes_a_bag_that_says_what_the_recording_says(tmp_path: Path) -> None:
    src = tmp_path / "run.mcap"
    pioneer_recording(src, ros2=False)
    before = src.read_bytes()
    out = tmp_path / "run-ros2.mcap"
    proc = run("convert", str(src), str(out), "--ros2")
    assert proc.returncode == 0 and "ROS 2 messages" in proc.stderr, proc.stderr
    assert src.read_bytes() == before  # never written to
    msgs = _read(out)
    states = [c for c in info(src).channels if c.topic == "/pioneer/state"][0].count
    assert len(msgs["/pioneer/odom"]) == len(msgs["/pioneer/battery"]) == states
    # the raw frames are the recording's, byte for byte: dump --file reads both alike
    assert [f.frame for f in read_capture(out, "arcos")] == [
        f.frame for f in read_capture(src, "arcos")
    ]
    # a bag folder, as ros2 bag record makes one: metadata.yaml read by rosbags' own reader
    folder = tmp_path / "run_bag"
    assert run("convert", str(src), str(folder), "--ros2").returncode == 0
    assert sorted(p.name for p in folder.iterdir()) == ["metadata.yaml", "run_bag_0.mcap"]
    from rosbags.rosbag2 import Reader

    with Reader(folder) as reader:
        assert reader.message_count == sum(len(v) for v in msgs.values())
        assert {c.topic for c in reader.connections} == set(msgs)


def test_convert_keeps_the_users_files(tmp_path: Path) -> None:
    src = tmp_path / "run.mcap"
    pioneer_recording(src, ros2=False)
    out = tmp_path / "out.mcap"
    out.write_bytes(b"mine")
    assert "exists" in one_line_error(run("convert", str(src), str(out), "--ros2"), 2)
    assert out.read_bytes() == b"mine"
    folder = tmp_path / "bag"
    folder.mkdir()
    (folder / "keep").write_text("x")
    assert "never replaced" in one_line_error(run("convert", str(src), str(folder), "--ros2"), 2)
    assert [p.name for p in folder.iterdir()] == ["keep"]
    assert "--ros2" in one_line_error(run("convert", str(src), str(tmp_path / "o.mcap")), 2)
    assert run("convert", str(src), str(out), "--ros2", "--overwrite").returncode == 0
    err = one_line_error(run("convert", str(out), str(tmp_path / "again.mcap"), "--ros2"), 1)
    assert "ROS 2 bag already" in err and not (tmp_path / "again.mcap").exists()


def test_a_killed_bag_recording_keeps_its_chunks(tmp_path: Path) -> None:
    path = tmp_path / "killed.mcap"
    with running("record", "--pioneer", "sim", "--ros2", "-o", str(path)) as proc:
        wait_for(lambda: path.exists() and info(path).messages >= 20, timeout=60,
                 what="the first chunks of the bag")  # fmt: skip
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(10)
    kept = info(path)
    assert not kept.summary and kept.messages >= 20
    stats = recover(path, tmp_path / "whole.mcap")
    msgs = _read(tmp_path / "whole.mcap")  # rosbags reads the recovered bag whole
    assert sum(len(v) for v in msgs.values()) == stats.messages >= kept.messages
    assert msgs["/pioneer/odom"]


def test_a_live_view_of_a_bag_recording_gets_robocli_json(tmp_path: Path) -> None:
    """record --ros2 --foxglove: the file is CDR, the live view's mirror still gets the
    JSON messages of robocli's schemas (what the viewer's panels read)."""
    import json

    from robocli.io.record import Recorder

    class Mirror:
        def __init__(self) -> None:
            self.schemas: dict[int, str] = {}
            self.got: list[tuple[str, dict[str, object]]] = []

        def channel(self, topic: str, schema: str | None, **_: object) -> int:
            self.schemas[len(self.schemas) + 1] = schema or ""
            return len(self.schemas)

        def write(self, cid: int, data: bytes, *_: object) -> None:
            self.got.append((self.schemas[cid], json.loads(data)))

    mirror = Mirror()
    path = tmp_path / "live.mcap"
    from robocli.io import schemas as S

    with Recorder(path, ros2=True) as rec:
        rec.mirror(mirror)
        scan = S.laser_scan(10**18, "laser/laser", -1.0, 1.0, [1.0, 2.0, 3.0])

        def put() -> None:
            rec.write(rec.channel("/laser/scan", "foxglove.LaserScan"),
                      json.dumps(scan).encode(), 10**18)  # fmt: skip

        rec.put(put, ())
    assert mirror.got == [("foxglove.LaserScan", scan)]
    msgs = _read(path)
    assert list(msgs["/laser/scan"][0].ranges) == [1.0, 2.0, 3.0]  # type: ignore[attr-defined]
