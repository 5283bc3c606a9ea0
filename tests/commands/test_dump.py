"""``robocli dump pioneer``: captures streamed in bounded memory, time order, short lines,
handshake names by phase, JSON Lines, recording, a closed pipe, Ctrl-C (issue 7: 9, 15)."""

from __future__ import annotations

import errno
import json
import os
import random
import re
import signal
import subprocess
import time
from pathlib import Path
from typing import BinaryIO

import pytest

from robocli.io import capture
from robocli.io.capture import CaptureStats, read_capture
from tests.commands.helpers import DATA, bytes_read, one_line_error, peak_rss_kib, run, running
from tests.paths import EXAMPLES

STAMP = re.compile(r"^\s*(\d+\.\d+) (->|<-)\s+(\S+)")


def packet_lines(stdout: str) -> list[tuple[float, str, str]]:
    """(t, arrow, name) of each packet line of a text dump."""
    return [(float(m[1]), m[2], m[3]) for m in map(STAMP.match, stdout.splitlines()) if m]


def raw_capture(tmp_path: Path, trace: str, direction: str | None) -> Path:
    """The bytes of a .jsonl trace as a raw capture: one direction, or both in time order."""
    data = b""
    for line in (DATA / trace).read_text().splitlines():
        record = json.loads(line)
        if "hex" in record and direction in (None, record["dir"]):
            data += bytes.fromhex(record["hex"])
    path = tmp_path / f"{trace}.{direction or 'both'}.bin"
    path.write_bytes(data)
    return path


@pytest.mark.parametrize(
    ("robot", "named", "summary"),
    [("pioneer", "ARCOS packet", "0 packets decoded"),
     ("arm", "Simple Message frame", "0 messages decoded")],
)  # fmt: skip
def test_dev_zero_is_given_up_after_a_bound_of_bytes_without_a_frame(
    robot: str, named: str, summary: str
) -> None:
    """Once it read /dev/zero for 10 minutes at 80 % CPU; now one line, exit 1, after
    MAX_GAP bytes (the timeout only bounds a failure)."""
    line = one_line_error(run("dump", robot, "--file", "/dev/zero", timeout=300), 1)
    assert f"/dev/zero: no {named} in 16 MiB, up to byte " in line, line
    assert "stopped reading" in line and summary in line, line
    dropped = int(re.findall(r"(\d+) bytes dropped", line)[0])
    assert capture.MAX_GAP < dropped <= capture.MAX_GAP + capture.CHUNK


def test_a_gap_without_frames_stops_reading_after_the_frames_before_it(tmp_path: Path) -> None:
    good = raw_capture(tmp_path, "a_simpleConnect.jsonl", "s2c").read_bytes()
    path = tmp_path / "gap.bin"
    path.write_bytes(good + bytes(4 * capture.CHUNK) + good)
    stats = CaptureStats()
    frames = []
    with pytest.raises(capture.NoFrameError, match="no ARCOS packet in 131072 bytes, up to"):
        frames.extend(read_capture(path, stats=stats, max_gap=2 * capture.CHUNK))
    assert len(frames) == stats.frames > 30  # the frames before the gap, then the error
    jsonl = tmp_path / "events.jsonl"  # lines without a frame count as well
    jsonl.write_text('{"t": 0, "event": "x"}\n' * 10_000)
    with pytest.raises(capture.NoFrameError):
        list(read_capture(jsonl, max_gap=50_000))


def _writer(fifo: Path, proc: subprocess.Popen[str]) -> BinaryIO:
    """The writing end of ``fifo``, once ``proc`` has opened its reading end."""
    deadline = time.monotonic() + 30
    while True:
        try:
            fd = os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)
        except OSError as exc:  # ENXIO: no reader yet
            assert exc.errno == errno.ENXIO and proc.poll() is None and time.monotonic() < deadline
            time.sleep(0.02)
            continue
        os.set_blocking(fd, True)
        return os.fdopen(fd, "wb")


def test_a_long_stream_reads_in_bounded_memory_and_stops_on_ctrl_c(tmp_path: Path) -> None:
    """A capture from a pipe: gaps shorter than MAX_GAP between packets go on being read,
    in constant memory, until Ctrl-C."""
    fifo = tmp_path / "capture.bin"
    os.mkfifo(fifo)
    frame = raw_capture(tmp_path, "a_simpleConnect.jsonl", "s2c").read_bytes()
    gap = bytes(capture.MAX_GAP - 2 * capture.CHUNK)
    with running("dump", "pioneer", "--file", str(fifo)) as proc:
        with _writer(fifo, proc) as feed:
            for _ in range(5):  # 80 MiB: five times the gap limit
                feed.write(gap + frame)
                feed.flush()
            peak = peak_rss_kib(proc.pid)
            read = bytes_read(proc.pid)
            assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
            proc.send_signal(signal.SIGINT)
            out, err = proc.communicate(timeout=30)
    assert read >= 4 * len(gap), read
    assert peak < 150_000, f"peak RSS {peak} KiB after reading {read} bytes"
    assert proc.returncode == 130 and err.strip() == "robocli: interrupted", err
    assert "SYNC2-reply" in out


@pytest.mark.parametrize("kind", ["empty", "random", "broken-jsonl", "deep-jsonl"])
def test_a_capture_without_packets_exits_1_saying_what_was_dropped(
    tmp_path: Path, kind: str
) -> None:
    rng = random.Random(7)
    if kind == "empty":
        path, dropped = tmp_path / "empty.bin", 0
        path.write_bytes(b"")
    elif kind == "random":
        data = bytes(b for b in rng.randbytes(5000) if b != 0xFA)  # no frame can start
        path, dropped = tmp_path / "random.bin", len(data)
        path.write_bytes(data)
    elif kind == "deep-jsonl":  # once a RecursionError traceback
        path, dropped = tmp_path / "deep.jsonl", 100_000
        path.write_text("[" * 100_000 + "\n")
    else:
        lines = ["not json", '{"t": 0, "dir": "s2c", "hex": "zz"}', "[1, 2]", '{"hex": "fafb03"}']
        path = tmp_path / "broken.jsonl"
        path.write_text("\n".join(lines) + "\n")
        dropped = sum(len(line) for line in lines[:3]) + 3  # the last one: a partial frame
    line = one_line_error(run("dump", "pioneer", "--file", str(path)), 1)
    assert line.endswith(f": 0 packets decoded, {dropped} bytes dropped"), line


def test_capture_reader_counts_what_it_dropped(tmp_path: Path) -> None:
    good = raw_capture(tmp_path, "a_simpleConnect.jsonl", "s2c").read_bytes()
    path = tmp_path / "noisy.bin"
    path.write_bytes(b"\x01\x02\x03" + good + b"\xfa\xfb\x10")  # garbage, frames, a stub
    stats = CaptureStats()
    frames = list(read_capture(path, stats=stats))
    assert stats.frames == len(frames) > 30 and stats.bytes_read == len(good) + 6
    assert stats.dropped_bytes == 6


def test_recorded_trace_in_time_order_with_short_lines() -> None:
    proc = run("dump", "pioneer", "--file", str(DATA / "c2_wander.jsonl"))
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    packets = packet_lines(proc.stdout)
    assert len(packets) > 100
    times = [t for t, _, _ in packets]
    assert times == sorted(times)
    lines = proc.stdout.splitlines()
    assert max(map(len, lines)) <= 160 and "=None" not in proc.stdout
    full = run("-v", "dump", "pioneer", "--file", str(DATA / "c2_wander.jsonl"), "-n", "12")
    assert max(map(len, full.stdout.splitlines())) > 160  # -v: every field, uncut


def test_raw_robot_side_names_the_sync2_reply_not_close(tmp_path: Path) -> None:
    path = raw_capture(tmp_path, "a_simpleConnect.jsonl", "s2c")
    proc = run("dump", "pioneer", "--file", str(path), "-n", "4")
    assert proc.returncode == 0, proc.stderr
    names = [
        line.split()[1 if line.startswith(("->", "<-")) else 0] for line in proc.stdout.splitlines()
    ]
    assert names[:3] == ["SYNC0", "SYNC1", "SYNC2-reply"], proc.stdout
    assert "CLOSE" not in proc.stdout and "name=AMRISim" in proc.stdout
    assert names[3] == "CONFIG"


def test_raw_capture_of_both_sides_decodes_batteryinfo(tmp_path: Path) -> None:
    path = raw_capture(tmp_path, "a_simpleConnect.jsonl", None)
    proc = run("dump", "pioneer", "--file", str(path))
    assert proc.returncode == 0, proc.stderr
    assert "error" not in proc.stdout and "unpack_from" not in proc.stdout
    assert re.search(r"^-> BATTERYINFO\s+arg=1$", proc.stdout, re.M), proc.stdout
    assert "SYNC2-reply" in proc.stdout and "CLOSE" not in proc.stdout.split("OPEN")[0]


def test_json_lines_rounded() -> None:
    proc = run("dump", "pioneer", "--file", str(DATA / "a_simpleConnect.jsonl"), "--json")
    assert proc.returncode == 0, proc.stderr
    records = [json.loads(line) for line in proc.stdout.splitlines()]
    assert [r["name"] for r in records[:6]] == [
        "SYNC0", "SYNC0-reply", "SYNC1", "SYNC1-reply", "SYNC2", "SYNC2-reply",
    ]  # fmt: skip
    assert records[5]["fields"]["subtype"] == "p3dx" and records[5]["dir"] == "s2c"
    sip = next(r["fields"] for r in records if r["name"] == "SIP")
    assert sip["battery"] == 130 and len(sip["sonar"]) == 16
    assert all(len(str(r["t_rel"]).split(".")[-1]) <= 6 for r in records)
    assert {r["t"] for r in records} == {None}  # a trace says not when it began


def test_live_session_recorded_then_replayed_the_same(tmp_path: Path) -> None:
    record = tmp_path / "session.jsonl"
    live = run("dump", "pioneer", "sim", "-n", "30", "--output", str(record), timeout=30)
    assert live.returncode == 0, live.stderr
    packets = packet_lines(live.stdout)
    assert len(packets) == 30 and [t for t, _, _ in packets] == sorted(t for t, _, _ in packets)
    replay = run("dump", "pioneer", "--file", str(record))
    assert replay.returncode == 0, replay.stderr
    assert [(a, n) for _, a, n in packet_lines(replay.stdout)] == [(a, n) for _, a, n in packets]
    start, first = (json.loads(x) for x in record.read_text().splitlines()[:2])
    assert start["event"] == "start" and abs(start["unix_time"] - time.time()) < 600
    assert set(first) == {"t", "dir", "hex"} and first["dir"] == "c2s"


def test_output_needs_a_jsonl_name(tmp_path: Path) -> None:
    line = one_line_error(run("dump", "pioneer", "sim", "-o", str(tmp_path / "x.txt")), 2)
    assert ".jsonl" in line and "x.txt" in line


def test_a_closed_pipe_ends_quietly() -> None:
    with running("dump", "pioneer", "sim") as proc:
        assert proc.stdout is not None
        for _ in range(3):
            assert "SYNC" in proc.stdout.readline()
        proc.stdout.close()
        assert proc.wait(timeout=20) == 0
        assert proc.stderr is not None and proc.stderr.read() == ""


@pytest.mark.parametrize(
    ("trace", "name", "field"),
    [
        ("h_laser_wander.jsonl", "SIM_LASER", r"readings=(32|21)\(min \d+\)"),
        ("k_laser_newcmds.jsonl", "SIM_LASER_A", r"ranges=(32|21)\(min \d+\)"),
        ("i_simstat.jsonl", "SIM_STAT", r"latitude=-?\d+"),
    ],
)
def test_simulator_laser_and_simstat_decoded(trace: str, name: str, field: str) -> None:
    proc = run("dump", "pioneer", "--file", str(DATA / trace))
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    lines = [line for line in proc.stdout.splitlines() if f"<- {name} " in line]
    assert lines and all(re.search(field, line) and len(line) <= 160 for line in lines), lines[:2]
    assert "error=" not in proc.stdout


def test_an_overlong_jsonl_line_is_dropped_and_reading_goes_on(tmp_path: Path) -> None:
    good = (DATA / "a_simpleConnect.jsonl").read_text()
    huge = '{"t": 0, "dir": "s2c", "hex": "' + "00" * capture.MAX_LINE + '"}\n'
    path = tmp_path / "huge.jsonl"
    path.write_text(huge + good)
    stats = CaptureStats()
    frames = list(read_capture(path, stats=stats))
    expected = list(read_capture(DATA / "a_simpleConnect.jsonl"))
    assert frames == expected and stats.dropped_bytes == len(huge)


def test_live_dump_of_a_simulators_laser() -> None:
    proc = run("dump", "pioneer", "sim", "--laser", "-n", "40", timeout=30)
    assert proc.returncode == 0, proc.stderr
    lasers = [line for line in proc.stdout.splitlines() if "<- SIM_LASER " in line]
    assert lasers and all(
        re.search(r"total=181 first=\d+ readings=\d+\(min \d+\)", x) for x in lasers
    )


def test_ctrl_c_shows_the_close_sequence_last() -> None:
    with running("dump", "pioneer", "sim") as proc:
        assert proc.stdout is not None
        while "<- SIP" not in proc.stdout.readline():
            pass
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=20)
    assert proc.returncode == 130 and err.strip() == "robocli: interrupted", err
    tail = [name for _, _, name in packet_lines(out)][-4:]
    assert tail == ["VEL", "RVEL", "ENABLE", "CLOSE"], out[-400:]


def test_laser_commands_named_for_a_simulator_as_the_trace_decoder_does() -> None:
    proc = run("dump", "pioneer", "--file", str(DATA / "h_laser_wander.jsonl"))
    assert proc.returncode == 0, proc.stderr
    expected = {  # the names and arguments in h_laser_wander.txt
        "GRIPPERVAL|sim:OLD_LRF_CFG_START": "-90", "GRIPREQUEST|sim:OLD_LRF_CFG_END": "90",
        "GYROCALCW|sim:OLD_LRF_CFG_INC": "100", "ADSEL|sim:OLD_LRF_ENABLE": "2",
    }  # fmt: skip
    for name, arg in expected.items():
        assert re.search(rf"-> {re.escape(name)} arg={arg}$", proc.stdout, re.M), name
    plain = run("dump", "pioneer", "--file", str(DATA / "a_simpleConnect.jsonl"))
    assert "sim:" not in plain.stdout  # AMRISim, but no laser commands were sent


def test_a_terminal_that_cannot_show_an_ellipsis_gets_three_dots() -> None:
    """A latin-1 or ASCII terminal once got a UnicodeEncodeError traceback on the first
    shortened line."""
    import os

    env = {**os.environ, "PYTHONIOENCODING": "ascii"}
    capture = EXAMPLES / "pioneer_drive.jsonl"
    proc = run("dump", "pioneer", "--file", str(capture), "-n", "40", env=env)
    assert proc.returncode == 0, proc.stderr
    cut = [line for line in proc.stdout.splitlines() if line.endswith("...")]
    assert cut and all(len(line) <= 160 for line in proc.stdout.splitlines())
