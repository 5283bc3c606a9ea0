"""``sim pioneer --replay`` and ``sim abb --replay``: the real clients, over TCP, receive the
recorded robot's stream (its SIPs and laser, its joint states) byte for byte."""

from __future__ import annotations

import math
import socket
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from robocli.devices.arm import Arm
from robocli.devices.pioneer import Pioneer
from robocli.errors import RobocliError
from robocli.io.record.replay import RecordedPackets
from robocli.sim.abb.replay import AbbReplay
from robocli.sim.pioneer.replay import PioneerReplay
from robocli.sim.replay import FrameSchedule
from tests.io.readback import by_topic, decoded, frame_of
from tests.io.recordings import record_pioneer_drive
from tests.waiting import wait_for

Frames = list[tuple[str, bytes]]


@pytest.fixture
def pioneer_recording(pioneer_url: str, tmp_path: Path) -> Path:
    """A Pioneer driving a curve with its laser on, recorded from the handshake on."""
    path = tmp_path / "pioneer.mcap"
    record_pioneer_drive(path, pioneer_url)
    return path


def _sips(frames: Frames) -> list[bytes]:
    return [p for d, p in frames if d == "rx" and p[0] & 0xF0 == 0x30]


def _laser(frames: Frames) -> list[bytes]:
    return [p for d, p in frames if d == "rx" and p[0] in (0x60, 0x61)]


def test_pioneer_client_gets_the_recorded_stream(pioneer_recording: Path) -> None:
    topics = by_topic(pioneer_recording)
    recorded = [decoded(i) for i in topics["/pioneer/state"]]
    last = (recorded[-1]["x"], recorded[-1]["y"], recorded[-1]["th"])
    raw = [frame_of(i) for i in topics["/pioneer/raw/rx"]]
    recorded_sips = [f[3:-2] for f in raw if f[3] & 0xF0 == 0x30]
    recorded_laser = [f[3:-2] for f in raw if f[3] in (0x60, 0x61)]
    seen: Frames = []
    with PioneerReplay(RecordedPackets(pioneer_recording), speed=2.0) as replay:
        url = replay.serve_tcp("127.0.0.1", 0)
        with Pioneer.connect(url, listeners=[lambda d, p, t: seen.append((d, p))],
                             laser=True) as robot:  # fmt: skip
            poses = []
            wait_for(lambda: poses.append(robot.pose) or
                     len(_sips(seen)) >= len(recorded_sips), what="every recorded SIP")  # fmt: skip
            # the listener sees a SIP before the client's state takes it in
            wait_for(lambda: poses.append(robot.pose) or _same(poses[-1], last),
                     what="the last recorded pose")  # fmt: skip
            wait_for(lambda: len(_laser(seen)) >= len(recorded_laser), what="every laser packet")
            wait_for(lambda: replay.schedule.finished, what="the end of the recording")
    # the recorded SIPs, every one, in order, byte for byte
    assert _sips(seen) == recorded_sips
    # and its laser packets, sent after the SIPs they followed
    assert recorded_laser and _laser(seen) == recorded_laser
    # so the client decodes the recorded poses: each one it saw is the recording's, in order
    xyth = [(r["x"], r["y"], r["th"]) for r in recorded]
    k = 0
    for pose in poses:
        while k < len(xyth) and not _same(pose, xyth[k]):
            k += 1
        assert k < len(xyth), f"{pose} is not a recorded pose after the previous one"
    assert last[0] > 0.01, "the recorded robot drove"


def test_pioneer_replay_sends_the_laser_only_from_the_clients_request(
        pioneer_recording: Path) -> None:  # fmt: skip
    """As the live simulator: a client that did not ask for the laser gets none of the
    recorded laser packets (ARIA logs each one no handler wanted); after its request, whole
    recorded scans, from the first packet of a scan on."""
    raw = [frame_of(i)[3:-2] for i in by_topic(pioneer_recording)["/pioneer/raw/rx"]]
    recorded_laser = [f for f in raw if f[0] == 0x61]
    assert recorded_laser, "the recording has its laser"
    seen: Frames = []
    with PioneerReplay(RecordedPackets(pioneer_recording), speed=4.0, loop=True) as replay:
        url = replay.serve_tcp("127.0.0.1", 0)
        with Pioneer.connect(url, listeners=[lambda d, p, t: seen.append((d, p))]) as robot:
            wait_for(lambda: replay.schedule.laps >= 1, what="a whole lap of the recording")
            assert _sips(seen) and not _laser(seen)
            assert replay.withheld >= len(recorded_laser)
            robot.sim.start_laser()
            scan = robot.sim.wait_for_laser(30.0)
            assert len(scan.ranges) == 181
    got = _laser(seen)
    assert got[0][3:5] == b"\0\0", "the first packet sent begins a scan"
    assert all(p in recorded_laser for p in got)


def _same(a: Any, b: Any) -> bool:
    return (abs(a[0] - b[0]) < 1e-9 and abs(a[1] - b[1]) < 1e-9
            and abs(math.remainder(a[2] - b[2], 2 * math.pi)) < 1e-9)  # fmt: skip


def test_pioneer_replay_answers_the_recorded_identity(pioneer_recording: Path) -> None:
    with PioneerReplay(RecordedPackets(pioneer_recording)) as replay:
        url = replay.serve_tcp("127.0.0.1", 0)
        with Pioneer.connect(url) as robot:
            assert robot.config is not None
            assert (robot.identity.name, robot.identity.subtype) == ("robocli-sim", "p3dx")
            robot.set_velocity(1.0, 0.0)  # taken, not acted on
            robot.wait_for_sip()
        state = replay.snapshot()
        assert state.sim_time == 0.0 and state.trans_vel == 0.0  # nothing moved
        assert state.sessions == 1


def test_schedule_spacing_speed_and_loop() -> None:
    frames = [(10.0, b"a"), (10.5, b"b"), (11.0, b"c")]
    s = FrameSchedule(frames, speed=2.0, loop=True)
    assert s.due(100.0) == []  # not started
    s.restart(100.0)
    assert s.due(100.0) == [b"a"]
    assert s.due(100.2) == []
    assert s.due(100.25) == [b"b"]
    assert s.due(100.5) == [b"c"]
    assert s.period == pytest.approx(1.5)
    assert s.due(100.74) == []
    assert s.due(100.75) == [b"a"] and s.laps == 1
    once = FrameSchedule(frames)
    once.restart(0.0)
    assert once.due(5.0) == [b"a", b"b", b"c"] and once.finished
    with pytest.raises(RobocliError):
        FrameSchedule(frames, speed=0)


def test_replay_needs_its_link(pioneer_recording: Path) -> None:
    with pytest.raises(RobocliError, match="no raw sm channel"):
        AbbReplay(RecordedPackets(pioneer_recording))


def test_arm_client_gets_the_recorded_joint_states(arm_recording: Path) -> None:
    topics = by_topic(arm_recording)
    wanted = [(tuple(d["position"]), d["robot_time"])
              for d in (decoded(i) for i in topics["/arm/joint_feedback"])]  # fmt: skip
    positions = [tuple(decoded(i)["position"]) for i in topics["/arm/joint_states"]]
    recorded_frames = [frame_of(i) for i in topics["/arm/raw/state/rx"]]
    frames: list[bytes] = []
    samples: list[Any] = []
    with AbbReplay(RecordedPackets(arm_recording)) as replay:
        _, state = replay.serve_tcp("127.0.0.1", 0, 0)
        port = int(state.rsplit(":", 1)[1])
        with Arm.connect("127.0.0.1", 0, port, motion=False, listeners=[
                lambda d, f, t: frames.append(f) if d == "rx" else None]) as arm:  # fmt: skip
            arm.add_listener(samples.append, kind="samples")
            wait_for(lambda: len(frames) >= len(recorded_frames),
                     what="every recorded state frame")  # fmt: skip
    # the recorded state stream, every frame, in order, byte for byte
    assert frames == recorded_frames
    # which the client decodes into the recorded joint states (those before its sample
    # listener was added excepted)
    feedback = [(s.joints, s.robot_time) for s in samples if s.source == "joint_feedback"]
    assert feedback and feedback == wanted[len(wanted) - len(feedback) :]
    plain = [s.joints for s in samples if s.source == "joint_position"]
    assert plain == positions[len(positions) - len(plain) :]
    assert max(abs(v) for v in wanted[-1][0]) > 0.1, "the recorded arm moved"


class MemoryPackets:
    """A :class:`~robocli.sim.replay.PacketSource` that is no file: a simulator replays what
    any source gives it."""

    name = "memory"

    def __init__(self, frames: list[tuple[float, bytes]], meta: dict[str, str]) -> None:
        self._frames, self._meta = frames, meta

    def frames(self, protocol: str, direction: str) -> list[tuple[float, bytes]]:
        assert (protocol, direction) == ("sm", "rx:state")
        return self._frames

    def link_metadata(self, protocol: str) -> dict[str, str]:
        return self._meta


def test_a_simulator_replays_any_packet_source() -> None:
    frames = [(0.0, b"first"), (0.01, b"second"), (0.02, b"third")]
    source = MemoryPackets(frames, {"protocol": "sm-be", "real_size": "8"})
    with AbbReplay(source, speed=4.0) as replay:
        assert (replay.controller.byteorder, replay.path) == (">", "memory")
        _, state = replay.serve_tcp("127.0.0.1", 0, 0)
        with socket.create_connection(("127.0.0.1", int(state.rsplit(":", 1)[1])), 10) as s:
            got = b""
            while len(got) < len(b"firstsecondthird"):
                chunk = s.recv(64)
                assert chunk, "the replay closed the state port"
                got += chunk
    assert got == b"firstsecondthird"


def _cli(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "robocli", "sim", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip


def _stop(proc: subprocess.Popen[str]) -> None:
    proc.terminate()
    proc.wait(timeout=30)
    for stream in (proc.stdout, proc.stderr):
        if stream is not None:
            stream.close()


def test_sim_pioneer_replay_cli(pioneer_recording: Path) -> None:
    proc = _cli("pioneer", "--replay", str(pioneer_recording), "--port", "0", "--speed", "4")
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert "replaying" in line, line
        url = line.split(" on ", 1)[1].strip()
        with Pioneer.connect(url) as robot:
            robot.wait_for_sip()
    finally:
        _stop(proc)


def test_sim_abb_replay_cli(arm_recording: Path) -> None:
    proc = _cli("abb", "--replay", str(arm_recording), "--motion-port", "0",
                "--state-port", "0")  # fmt: skip
    try:
        assert proc.stdout is not None
        text = ""
        while "state" not in text or "motion" not in text:
            line = proc.stdout.readline()
            assert line, proc.stderr.read() if proc.stderr else ""
            text += line
        assert "replaying" in text, text
    finally:
        _stop(proc)


@pytest.mark.parametrize("robot", ["pioneer", "abb"])
def test_sim_speed_needs_replay(robot: str) -> None:
    result = subprocess.run([sys.executable, "-m", "robocli", "sim", robot, "--speed", "2"],
                            capture_output=True, text=True, timeout=60)  # fmt: skip
    assert result.returncode == 2, result.stderr
