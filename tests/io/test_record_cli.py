"""``robocli record`` and ``robocli info`` as a user runs them: real processes against the
embedded simulators, ended by a duration, a count, Ctrl-C, SIGTERM, SIGKILL, a lost link
and a full disk; every file is read back with the ``mcap`` package's own readers."""

from __future__ import annotations

import contextlib
import json
import re
import signal
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from robocli.io.capture import CaptureWriter
from robocli.io.record import Recorder, info
from robocli.protocols import arcos
from robocli.sim.pioneer.server import PioneerSim
from tests.commands.helpers import ROBOCLI, one_line_error, run, running
from tests.io.readback import by_topic, decoded, frame_of, messages, stream_messages
from tests.waiting import wait_for


def _json_dump(*args: str) -> list[dict[str, Any]]:
    proc = run("dump", *args, "--json")
    assert proc.returncode == 0, proc.stderr
    return [json.loads(line) for line in proc.stdout.splitlines()]


def test_record_all_three_for_a_duration(tmp_path: Path) -> None:
    path = tmp_path / "all.mcap"
    proc = run("record", "--pioneer", "sim", "--arm", "sim", "--hub", "sim", "--sensors",
               "imu,adc:200,laser,camera,gps", "-d", "2", "-o", str(path))  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert f"to {path}" in proc.stderr.splitlines()[-1]
    out = run("info", str(path), "--json")
    assert out.returncode == 0, out.stderr
    summary = json.loads(out.stdout)
    assert summary["summary"] is True and summary["compression"] == ["zstd"]
    schemas = {c["topic"]: c["schema"] for c in summary["channels"] if c["count"]}
    for topic, schema in {
        "/pioneer/pose": "foxglove.PoseInFrame", "/pioneer/laser": "foxglove.LaserScan",
        "/arm/joint_feedback": "robocli.JointState", "/arm/tf": "foxglove.FrameTransforms",
        "/hub/imu": "robocli.Imu", "/hub/adc": "robocli.Adc",
        "/hub/camera": "foxglove.RawImage", "/hub/gps": "foxglove.LocationFix",
        "/hub/laser": "foxglove.LaserScan", "/pioneer/raw/rx": "robocli.RawFrame",
    }.items():  # fmt: skip
        assert schemas.get(topic) == schema, (topic, sorted(schemas))
    assert 1.0 < summary["duration_s"] < 30
    assert summary["start"] < summary["end"]
    pose = next(c for c in summary["channels"] if c["topic"] == "/pioneer/pose")
    assert 5 <= pose["rate_hz"] <= 20 and 0.05 < pose["largest_gap_s"] < 1.0
    text = run("info", str(path))
    assert text.returncode == 0 and "/hub/camera" in text.stdout and "Duration:" in text.stdout


def test_record_stops_after_count(tmp_path: Path) -> None:
    path = tmp_path / "count.mcap"
    proc = run("record", "--pioneer", "sim", "-n", "30", "-o", str(path))
    assert proc.returncode == 0, proc.stderr
    assert len(messages(path)) >= 30


def test_dump_reads_a_recording_as_the_live_capture(tmp_path: Path) -> None:
    """One session, recorded by the live dump's capture writer and by the recorder: dump
    --file decodes both into the same packets, each direction in the same order."""
    from robocli.devices.pioneer import Pioneer

    mcap, jsonl = tmp_path / "s.mcap", tmp_path / "s.jsonl"
    with PioneerSim("p3dx", time_scale=5.0) as sim:
        url = sim.serve_tcp("127.0.0.1", 0)
        with Recorder(mcap) as rec, CaptureWriter(jsonl) as capture:
            listener = rec.listener("pioneer", "arcos")

            def live(direction: str, payload: bytes, t: float) -> None:
                capture.write(t, direction, arcos.frame(payload))

            with Pioneer.connect(url, listeners=[listener, live], laser=True) as robot:
                rec.add(robot, listener.name)
                robot.set_velocity(0.1, 0.0)
                for _ in range(5):
                    robot.wait_for_sip()
    from_mcap = _json_dump("pioneer", "--file", str(mcap))
    from_jsonl = _json_dump("pioneer", "--file", str(jsonl))
    for way in ("c2s", "s2c"):  # as capture files say it
        ours = [(p["type"], p["name"], p["fields"]) for p in from_mcap if p["dir"] == way]
        live_ = [(p["type"], p["name"], p["fields"]) for p in from_jsonl if p["dir"] == way]
        assert ours == live_ and len(ours) > 5
    assert [p["t"] for p in from_mcap] == sorted(p["t"] for p in from_mcap)


def test_dump_arm_reads_a_recording_with_its_ports(tmp_path: Path) -> None:
    path = tmp_path / "arm.mcap"
    proc = run("record", "--arm", "sim", "-n", "40", "-o", str(path))
    assert proc.returncode == 0, proc.stderr
    packets = _json_dump("arm", "--file", str(path), "-n", "20")
    assert len(packets) == 20
    assert {p["port"] for p in packets} == {"state"} and {p["dir"] for p in packets} == {"s2c"}
    assert {"JOINT_POSITION", "STATUS", "JOINT_FEEDBACK"} <= {p["name"] for p in packets}


def _pose_count(path: Path) -> int:
    try:
        channels = info(path).channels
    except Exception:
        return 0
    return sum(c.count for c in channels if c.topic == "/pioneer/pose")


@contextlib.contextmanager
def _recording(path: Path, *extra: str) -> Iterator[subprocess.Popen[str]]:
    """A ``robocli record`` process that has written complete chunks holding poses."""
    with running("record", "--pioneer", "sim", "-o", str(path), *extra) as proc:
        assert proc.stderr is not None
        assert "recording to" in proc.stderr.readline()
        wait_for(lambda: _pose_count(path) >= 5, what="poses written to disk")
        yield proc


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_and_sigterm_finish_the_file(tmp_path: Path, sig: signal.Signals) -> None:
    path = tmp_path / "stopped.mcap"
    with _recording(path) as proc:
        proc.send_signal(sig)
        assert proc.wait(30) == 130
        err = proc.stderr.read()
    assert "recorded" in err and "Traceback" not in err
    summary = info(path)
    assert summary.summary and not summary.truncated  # closed with its summary section
    items = messages(path)
    assert len(items) == summary.messages
    # the robot's stop and CLOSE went out before the file closed, and were recorded
    tx = [frame_of(i) for i in items if i[1].topic == "/pioneer/raw/tx"]
    assert tx[-1] == arcos.encode_command(arcos.Command.CLOSE, 1)
    for item in by_topic(path)["/pioneer/pose"]:
        decoded(item)


def test_sigkill_leaves_every_complete_chunk_readable(tmp_path: Path) -> None:
    path = tmp_path / "killed.mcap"
    with _recording(path) as proc:
        before = _pose_count(path)
        proc.kill()
        proc.wait(30)
    records, _cut = stream_messages(path)  # the mcap package's own stream reader
    summary = info(path)
    assert not summary.summary  # no summary: scanned, up to the last complete record
    poses = [c for c in summary.channels if c.topic == "/pioneer/pose"]
    assert poses and poses[0].schema == "foxglove.PoseInFrame" and poses[0].count >= before
    assert len(records) == summary.messages >= before
    assert summary.readable_bytes <= summary.size
    out = run("info", str(path))
    assert out.returncode == 0 and "Summary:     none" in out.stdout


def test_a_lost_link_ends_with_its_error_and_a_whole_file(tmp_path: Path) -> None:
    path = tmp_path / "lost.mcap"
    with PioneerSim("p3dx") as sim:
        url = sim.serve_tcp("127.0.0.1", 0)
        with running("record", "--pioneer", url, "-o", str(path)) as proc:
            assert "recording to" in proc.stderr.readline()
            wait_for(lambda: _pose_count(path) >= 3, what="poses on disk")
            sim.close()  # the robot goes away
            code = proc.wait(60)
            err = proc.stderr.read()
    assert code in (1, 3), err  # the link's own exit code: lost (1) or silent (3)
    assert "robocli: " in err and "Traceback" not in err and "recorded" in err
    assert info(path).summary


@contextlib.contextmanager
def _small_disk(tmp_path: Path, how: str) -> Iterator[tuple[Path, Any, int]]:
    """A place where files end after a few hundred KB, as on a full disk: (folder, the
    child's preexec_fn, the size). ``rlimit``: RLIMIT_FSIZE in the child (a write past it
    fails with EFBIG); ``tmpfs``: a 300 KiB tmpfs mounted for the test (root only; ENOSPC,
    after a short write)."""
    import resource  # (POSIX)

    if how == "rlimit":
        limit = 250_000  # a few one-second chunks of uncompressed 500 Hz ADC samples

        def small() -> None:  # in the child
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

        yield tmp_path, small, limit
        return
    where = tmp_path / "small"
    where.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=300k", "tmpfs", str(where)],
                             capture_output=True, text=True)  # fmt: skip
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs here: {mounted.stderr.strip() or 'not root'}")
    try:
        yield where, None, 300 << 10
    finally:
        subprocess.run(["umount", "-l", str(where)], capture_output=True)


@pytest.mark.parametrize("how", ["rlimit", "tmpfs"])
def test_a_full_disk_is_one_line_and_counts_what_the_file_holds(tmp_path: Path,
                                                                how: str) -> None:  # fmt: skip
    with _small_disk(tmp_path, how) as (where, preexec, limit):
        path = where / "full.mcap"
        proc = subprocess.run(
            [*ROBOCLI, "record", "--hub", "sim", "--sensors", "adc:500", "--compression", "none",
             "-d", "120", "-o", str(path)],
            capture_output=True, text=True, timeout=90, stdin=subprocess.DEVNULL,
            preexec_fn=preexec,
        )  # fmt: skip
        assert proc.returncode == 1, proc.stderr
        lines = proc.stderr.strip().splitlines()  # what it recorded, then the one error line
        assert [line for line in lines if line.startswith("robocli: ")] == lines[-1:]
        assert "failed" in lines[-1] and "last complete chunk" in lines[-1]
        assert "Traceback" not in proc.stderr
        records, cut = stream_messages(path)
        assert records and path.stat().st_size <= limit
        said = re.search(r"recorded (\d+) messages", proc.stderr)
        assert said is not None, proc.stderr
        assert int(said.group(1)) == len(records)  # what it says is what the file holds
        # what did not fit is said: the messages of a chunk whose write failed ("N not
        # written"), or, when the disk filled between chunks, those handed to the recorder
        # after the failure ("N dropped (not written)")
        unwritten = re.findall(r", (\d+) (?:not written|dropped \(not written\))", proc.stderr)
        assert sum(map(int, unwritten)) > 0, proc.stderr


_CUT_AFTER_CHUNK = """
import resource, signal, sys
from robocli.io.record import Recorder, RecordingError
path, limit = sys.argv[1], int(sys.argv[2])
if limit:
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
rec = Recorder(path, compression="none", chunk_seconds=3600)  # one chunk, written at close
def one(i):
    rec.write(rec.channel("/t", None, encoding="x"), bytes([i]) * 100, 1000 + i)
for i in range(50):
    rec.put(one, (i,))
try:
    rec.close()
except RecordingError:
    pass
print(rec.stats.messages, rec.stats.lost)
"""


def test_a_chunk_whose_indexes_did_not_fit_is_counted(tmp_path: Path) -> None:
    """The disk fills after a chunk's own record, in the message indexes behind it: the
    chunk reads back whole, and the count says so."""
    from mcap.reader import make_reader

    whole = tmp_path / "whole.mcap"
    done = subprocess.run([*ROBOCLI[:1], "-c", _CUT_AFTER_CHUNK, str(whole), "0"],
                          capture_output=True, text=True, timeout=60)  # fmt: skip
    assert done.stdout.split() == ["50", "0"], done.stderr
    with whole.open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and len(summary.chunk_indexes) == 1
    index = summary.chunk_indexes[0]
    end = index.chunk_start_offset + index.chunk_length  # the chunk's record ends here
    cut = tmp_path / "cut.mcap"
    proc = subprocess.run([*ROBOCLI[:1], "-c", _CUT_AFTER_CHUNK, str(cut), str(end + 5)],
                          capture_output=True, text=True, timeout=60)  # fmt: skip
    records, was_cut = stream_messages(cut)
    assert was_cut and len(records) == 50
    assert proc.stdout.split() == ["50", "0"], proc.stderr


def test_usage_errors(tmp_path: Path) -> None:
    assert run("record", "-o", str(tmp_path / "x.mcap")).returncode == 2
    assert run("record", "--pioneer", "sim", "-o", str(tmp_path / "x.txt")).returncode == 2
    bad = run("record", "--hub", "sim", "--sensors", "smell", "-o", str(tmp_path / "x.mcap"))
    assert bad.returncode == 2 and "smell" in bad.stderr
    nodir = run("record", "--pioneer", "sim", "-o", str(tmp_path / "no" / "x.mcap"))
    assert "cannot write" in one_line_error(nodir, 2)
    notmcap = tmp_path / "notes.mcap"
    notmcap.write_text("hello")
    assert "not an MCAP file" in one_line_error(run("info", str(notmcap)), 2)
