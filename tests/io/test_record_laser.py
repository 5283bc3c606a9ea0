"""``record --laser``: a Hokuyo recorded into MCAP against the built-in simulator over real
sockets (issue 16): its streamed scans as foxglove.LaserScan stamped with the sensor's time,
its SCIP lines both ways in raw channels that ``dump laser --file`` decodes again; read back
with the ``mcap`` package's own reader."""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path

import pytest

from robocli.devices.laser import Laser, Scan
from robocli.io.record import RAW_SCHEMA, Recorder, info, raw_frames
from robocli.sim.hokuyo import HokuyoSim
from tests.commands.helpers import run, running
from tests.io.readback import by_topic, decoded
from tests.waiting import wait_for


@pytest.fixture
def laser_url() -> Iterator[str]:
    with HokuyoSim("utm-30lx", time_scale=2.0) as sim:
        yield sim.serve_tcp("127.0.0.1", 0)


def _record(url: str, path: Path, scans: int = 8) -> tuple[list[tuple[str, bytes]], list[Scan]]:
    """Record a laser from its handshake on while streaming ``scans`` scans; what a live
    dump's listener saw (direction, payload) and the scans the client decoded."""
    seen: list[tuple[str, bytes]] = []
    got: list[Scan] = []
    with Recorder(path) as rec:
        raw = rec.listener("laser", "scip2", url=url)

        def both(direction: str, payload: bytes, t: float) -> None:
            raw(direction, payload, t)
            seen.append((direction, payload))

        with Laser.connect(url, listeners=[both]) as laser:
            assert rec.add(laser, raw.name) == "laser"
            got.extend(laser.scans(scans))
        assert rec.stats.dropped == 0
    return seen, got


def test_scans_are_foxglove_laser_scans_on_the_sensor_clock(laser_url: str,
                                                             tmp_path: Path) -> None:  # fmt: skip
    path = tmp_path / "laser.mcap"
    _, got = _record(laser_url, path)
    topics = by_topic(path)
    items = topics["/laser/scan"]
    assert len(items) == len(got) == 8
    for item, scan in zip(items, got, strict=True):
        schema, channel, message = item
        assert schema.name == "foxglove.LaserScan"
        data = decoded(item)
        assert data["frame_id"] == "laser/laser"
        assert data["start_angle"] == pytest.approx(-3 * math.pi / 4)
        assert data["end_angle"] == pytest.approx(3 * math.pi / 4)
        want = [0.0 if math.isnan(r) else r for r in scan.ranges]
        assert data["ranges"] == pytest.approx(want)
        assert message.publish_time == int(scan.t * 1e9)  # the sensor's stamp, mapped
        stamp = data["timestamp"]
        assert stamp["sec"] * 10**9 + stamp["nsec"] == message.publish_time
        assert abs(message.log_time / 1e9 - scan.received) < 0.05  # when it arrived
    raws = {k: v[0][1] for k, v in topics.items() if "/raw/" in k}
    assert set(raws) == {"/laser/raw/tx", "/laser/raw/rx"}
    assert all(c.message_encoding == "json" and c.metadata["protocol"] == "scip2"
               for c in raws.values())  # fmt: skip
    assert all(i[0].name == RAW_SCHEMA for k, v in topics.items() if "/raw/" in k for i in v)


def test_raw_channels_give_back_every_line_both_ways(laser_url: str, tmp_path: Path) -> None:
    path = tmp_path / "laser.mcap"
    seen, _ = _record(laser_url, path)
    back = [(d, f) for _, d, f in raw_frames(path, "scip2")]
    # requests come back without their terminator (framed as the simulator frames them)
    want = [(d, p.rstrip(b"\n") if d == "tx" else p) for d, p in seen]
    assert [f for d, f in back if d == "tx"] == [p for d, p in want if d == "tx"]
    assert [f for d, f in back if d == "rx"] == [p for d, p in want if d == "rx"]
    assert ("tx", b"QT") in back and any(f.startswith(b"MD") for d, f in back if d == "tx")


def test_record_laser_cli_then_dump_laser_file(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    # a duration, not a count: what the sources sent while the others connected is counted
    # the moment the file is made, which on a loaded machine reached 60 before the first scan
    proc = run("record", "--laser", "sim", "--pioneer", "sim", "--no-laser", "-o", str(path),
               "-d", "1.5", timeout=90)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    topics = by_topic(path)
    assert len(topics["/laser/scan"]) >= 1
    assert "/pioneer/laser" not in topics  # --no-laser: the Pioneer simulator's laser is off
    tf = decoded(topics["/laser/tf"][0])  # on the robot, 18 mm ahead (the P3-DX's mount)
    assert (tf["parent_frame_id"], tf["child_frame_id"]) == ("pioneer/base_link", "laser/laser")
    assert tf["translation"] == {"x": 0.018, "y": 0.0, "z": 0.0}
    assert tf["rotation"] == {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
    assert len(topics["/laser/tf"]) == len(topics["/laser/scan"])
    dump = run("dump", "laser", "--file", str(path), "--json", timeout=60)
    assert dump.returncode == 0, dump.stderr
    lines = [json.loads(line) for line in dump.stdout.splitlines()]
    requests = [x["line"] for x in lines if x["dir"] == "c2s"]
    assert requests[:4] == ["QT", "VV", "PP", "II"]
    assert any(r.startswith("MD") for r in requests) and requests[-1] == "QT"
    frames = [x for x in lines if x["dir"] == "s2c" and x["line"].startswith("MD")]
    assert len(frames) >= len(topics["/laser/scan"])


def test_a_lost_laser_ends_the_recording_with_its_error_and_a_whole_file(tmp_path: Path) -> None:
    path = tmp_path / "lost.mcap"
    with HokuyoSim("utm-30lx") as sim:
        url = sim.serve_tcp("127.0.0.1", 0)
        with running("record", "--laser", url, "-o", str(path)) as proc:
            assert proc.stderr is not None
            assert "recording to" in proc.stderr.readline()
            wait_for(lambda: path.stat().st_size > 4096, what="scans on disk")
            sim.close()  # the scanner goes away
            code = proc.wait(60)
            err = proc.stderr.read()
    assert code == 1, err  # the link's own exit code: lost
    assert "robocli: " in err and "link lost" in err and "Traceback" not in err
    assert info(path).summary and len(by_topic(path)["/laser/scan"]) >= 1
