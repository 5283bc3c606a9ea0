"""``robocli plot``: figures of short real recordings of each robot kind made with the
simulators. The PNG is checked to exist; what was drawn is checked through what
:func:`~robocli.io.record.plot.plot` reports (points per line, scan returns and where they
fall), never through pixels."""

from __future__ import annotations

import json
import math
import struct
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("matplotlib")

from robocli.devices.arm import Arm
from robocli.devices.hub.client import Hub
from robocli.devices.pioneer import Pioneer
from robocli.errors import InvalidArgument
from robocli.hub_server import HubServer
from robocli.io import schemas as S
from robocli.io.record import Recorder
from robocli.io.record.links import json_text
from robocli.io.record.plot import plot
from tests.commands.helpers import one_line_error, run
from tests.io.readback import by_topic
from tests.waiting import wait_for

PNG = b"\x89PNG\r\n\x1a\n"


def _png(path: Path) -> None:
    assert path.read_bytes()[:8] == PNG


def test_a_pioneer_path_with_its_sonar_and_laser(pioneer_url: str, tmp_path: Path) -> None:
    path = tmp_path / "pioneer.mcap"
    with Recorder(path) as rec, Pioneer.connect(pioneer_url, laser=True) as robot:
        rec.add(robot)
        robot.enable_motors()
        robot.set_velocity(0.4, 0.3)
        for _ in range(20):
            robot.wait_for_sip()
        robot.sim.wait_for_laser(10)
    topics = by_topic(path)
    out = tmp_path / "path.png"
    result = plot(path, out, ["/pioneer/pose", "/pioneer/sonar", "/pioneer/laser"])
    _png(out)
    assert result.kind == "path"
    assert result.series == {"/pioneer/pose": len(topics["/pioneer/pose"])}
    assert result.scan_points > 0 and result.scan_extent is not None
    x0, x1, y0, y1 = result.scan_extent
    assert x1 - x0 > 1.0 and y1 - y0 > 1.0  # the returns spread over the walls around
    assert result.duration_s > 0


def test_scan_returns_are_put_in_the_odom_frame(tmp_path: Path) -> None:
    """A robot at (1, 2) heading +90 degrees sees one return 1 m ahead: it lies at (1, 3)."""
    path = tmp_path / "one.mcap"
    with Recorder(path) as rec:

        def write() -> None:
            pose = {"timestamp": S.stamp(1), "frame_id": "p/odom",
                    "pose": S.pose(1.0, 2.0, 0.0, S.quaternion_z(math.pi / 2))}  # fmt: skip
            rec.write(rec.channel("/p/pose", "foxglove.PoseInFrame"),
                      json_text(pose).encode(), 1_000)  # fmt: skip
            scan = S.laser_scan(2, "p/base_link", -0.5, 0.5, [0.0, 1.0, 0.0])
            rec.write(rec.channel("/p/laser", "foxglove.LaserScan"),
                      json_text(scan).encode(), 2_000)  # fmt: skip

        rec.put(write, ())
    result = plot(path, tmp_path / "one.png", ["/p/pose", "/p/laser"])
    assert result.scan_points == 1  # the zero ranges are no returns
    assert result.scan_extent is not None
    for got, want in zip(result.scan_extent, (1.0, 1.0, 3.0, 3.0), strict=True):
        assert got == pytest.approx(want, abs=1e-9)


def test_each_robot_s_scans_go_with_its_own_pose(tmp_path: Path) -> None:
    """Two robots: /a at (1, 2) heading +90 degrees, /b at (5, 5) heading 0, posed in that
    order; then /a's scan, one return 1 m ahead, lies at (1, 3), not 1 m ahead of /b."""
    path = tmp_path / "two.mcap"
    with Recorder(path) as rec:

        def write(name: str, ns: int, x: float, y: float, th: float) -> None:
            pose = {"timestamp": S.stamp(ns), "frame_id": f"{name}/odom",
                    "pose": S.pose(x, y, 0.0, S.quaternion_z(th))}  # fmt: skip
            rec.write(rec.channel(f"/{name}/pose", "foxglove.PoseInFrame"),
                      json_text(pose).encode(), ns)  # fmt: skip

        def scan(name: str, ns: int) -> None:
            data = S.laser_scan(ns, f"{name}/base_link", 0.0, 0.0, [1.0])
            rec.write(rec.channel(f"/{name}/laser", "foxglove.LaserScan"),
                      json_text(data).encode(), ns)  # fmt: skip

        rec.put(write, ("a", 1_000, 1.0, 2.0, math.pi / 2))
        rec.put(write, ("b", 1_500, 5.0, 5.0, 0.0))
        rec.put(scan, ("a", 2_000))
        rec.put(scan, ("b", 2_000))
    result = plot(path, tmp_path / "two.png", ["/a/pose", "/b/pose", "/a/laser", "/b/laser"])
    assert result.scan_points == 2
    assert result.scan_extent == pytest.approx((1.0, 6.0, 3.0, 5.0), abs=1e-9)


def test_an_arm_s_joints_against_time(abb: tuple[int, int], tmp_path: Path) -> None:
    motion, state = abb
    path = tmp_path / "arm.mcap"
    with Recorder(path) as rec, Arm.connect("127.0.0.1", motion, state, motion=False) as arm:
        rec.add(arm)
        wait_for(lambda: rec.stats.messages >= 60, what="arm states recorded")
    n = len(by_topic(path)["/arm/joint_feedback"])
    result = plot(path, tmp_path / "joints.png", ["/arm/joint_feedback"])
    _png(tmp_path / "joints.png")
    assert result.kind == "time"
    assert result.series == {f"/arm/joint_feedback joint_{i}": n for i in range(1, 7)}


def test_hub_fields_against_time(hub_server: HubServer, tmp_path: Path) -> None:
    path = tmp_path / "hub.mcap"
    with Recorder(path) as rec, Hub.connect("127.0.0.1", hub_server.port) as hub:
        rec.add(hub, sensors=("imu", "adc"))
        hub.subscribe("imu", rate=100)
        hub.subscribe("adc", rate=100, channels=0x0F)

        def enough() -> bool:
            hub.read("imu")
            hub.read("adc")
            return rec.stats.messages >= 100

        wait_for(enough, what="hub samples recorded")
    topics = by_topic(path)
    n_imu, n_adc = len(topics["/hub/imu"]), len(topics["/hub/adc"])
    result = plot(path, tmp_path / "hub.png", ["/hub/imu", "/hub/adc"],
                  ["linear_acceleration.z", "channels"])  # fmt: skip
    _png(tmp_path / "hub.png")
    width = len(json.loads(topics["/hub/adc"][0][2].data)["channels"])
    assert result.series == {
        "/hub/imu linear_acceleration.z": n_imu,
        **{f"/hub/adc channels[{k}]": n_adc for k in range(width)},
    }
    # each sample at its own acquisition time, not stacked at its reply's receive time
    assert result.distinct_times == result.series
    with pytest.raises(InvalidArgument, match="linear_acceleration.z"):
        plot(path, tmp_path / "x.png", ["/hub/imu"])  # which field? the error lists them
    with pytest.raises(InvalidArgument, match="no channel /hub/gps"):
        plot(path, tmp_path / "x.png", ["/hub/gps"])


def test_the_command(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    proc = run("record", "--pioneer", "sim", "-n", "200", "-o", str(path))
    assert proc.returncode == 0, proc.stderr
    out = tmp_path / "path.png"
    shown = run("plot", str(path), "-c", "/pioneer/pose", "-c", "/pioneer/laser", "-o", str(out))
    assert shown.returncode == 0, shown.stderr
    assert shown.stdout.startswith(f"plot written: {out} (path: /pioneer/pose (")
    _png(out)
    as_json = run("plot", str(path), "-c", "/pioneer/state", "-f", "battery", "-o", str(out),
                  "--json", "--overwrite")  # fmt: skip
    assert as_json.returncode == 0, as_json.stderr
    report = json.loads(as_json.stdout)
    assert report["kind"] == "time" and report["points"] > 0
    assert list(report["series"]) == ["/pioneer/state battery"]
    assert "numeric fields: x, y, th" in one_line_error(
        run("plot", str(path), "-c", "/pioneer/state", "-o", str(out), "--overwrite"), 2
    )
    again = run("plot", str(path), "-c", "/x", "-o", str(out), "--overwrite")
    assert "no channel" in one_line_error(again, 2)

    # cut short (as by a kill) inside its last chunk: drawn up to the chunk before, as many
    # poses as the mcap stream reader finds in the complete chunks (how many chunks a
    # recording has follows the machine's speed: no fixed count is assumed)
    whole = plot(path, out, ["/pioneer/pose"], overwrite=True).series["/pioneer/pose"]
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes()[: _last_chunk_start(path) + 16])
    complete = _complete(cut, "/pioneer/pose")
    drawn = plot(cut, out, ["/pioneer/pose"], overwrite=True).series["/pioneer/pose"]
    assert drawn == complete <= whole


def _last_chunk_start(path: Path) -> int:
    from mcap.reader import make_reader

    with path.open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.chunk_indexes
    return max(ci.chunk_start_offset for ci in summary.chunk_indexes)


def _complete(path: Path, topic: str) -> int:
    """Messages on ``topic`` that the mcap stream reader reads before the file's cut."""
    from mcap.exceptions import McapError
    from mcap.records import Channel, Message
    from mcap.stream_reader import StreamReader

    ids, n = set(), 0
    with path.open("rb") as f:
        try:
            for record in StreamReader(f).records:
                if isinstance(record, Channel) and record.topic == topic:
                    ids.add(record.id)
                elif isinstance(record, Message) and record.channel_id in ids:
                    n += 1
        except (McapError, EOFError, ValueError, struct.error):
            pass  # the cut
    return n


def test_without_matplotlib_one_line_says_how_to_install(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    assert run("record", "--pioneer", "sim", "-n", "20", "-o", str(path)).returncode == 0
    code = (
        "import sys; sys.modules['matplotlib'] = None; from robocli.cli import main; "
        f"sys.exit(main(['plot', {str(path)!r}, '-c', '/pioneer/pose', '-o', 'x.png']))"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60, cwd=tmp_path)  # fmt: skip
    assert "pip install 'robocli-robots[plot]'" in one_line_error(proc, 1)
    assert not (tmp_path / "x.png").exists()
