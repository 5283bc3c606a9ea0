"""A recorder never endangers the robot: a stalled disk drops with a count in bounded memory
while the client's threads go on; a failed disk is one error and the listeners keep quiet;
bytes that do not decode are counted and kept raw."""

from __future__ import annotations

import io
import threading
from pathlib import Path
from typing import Any

import pytest

from robocli.devices.pioneer import Pioneer
from robocli.errors import InvalidArgument
from robocli.io.record import Recorder, RecordingError, info
from robocli.protocols import arcos
from tests.io.readback import by_topic, frame_of
from tests.waiting import wait_for


class StalledDisk(io.RawIOBase):
    """A file whose writes block while ``stalled`` is clear (a disk that stopped answering),
    then land in memory; or fail with ``error`` set."""

    def __init__(self) -> None:
        self.data = bytearray()
        self.running = threading.Event()
        self.running.set()
        self.error: OSError | None = None
        self.blocked = threading.Event()

    def writable(self) -> bool:
        return True

    def write(self, b: Any) -> int:
        if not self.running.is_set():
            self.blocked.set()
            self.running.wait(60)
        if self.error is not None:
            raise self.error
        self.data += bytes(b)
        return len(b)

    def tell(self) -> int:
        return len(self.data)


def test_a_stalled_disk_drops_with_a_count_and_the_robot_goes_on(
    pioneer_url: str, tmp_path: Path
) -> None:
    disk = StalledDisk()
    rec = Recorder(disk, max_queue=40, chunk_seconds=0.05)
    try:
        with Pioneer.connect(pioneer_url, laser=True) as robot:
            rec.add(robot)
            robot.wait_for_sip()
            disk.running.clear()  # the disk stalls: the writer blocks in its next write
            wait_for(disk.blocked.is_set, what="the writer to block")
            wait_for(lambda: rec.stats.dropped > 50, what="drops")
            sips = robot.stats.sips
            wait_for(lambda: robot.stats.sips >= sips + 10, what="SIPs while the disk stalls")
            assert robot.alive
            assert robot.stats.as_dict()["listener_errors"] == 0
            assert rec.stats.queue_peak <= 40  # bounded: dropped, not queued
            disk.running.set()  # the disk answers again
            after = rec.stats.messages
            wait_for(lambda: rec.stats.messages > after + 10, what="recording to resume")
    finally:
        rec.close()
    path = tmp_path / "resumed.mcap"
    path.write_bytes(disk.data)
    summary = info(path)
    assert summary.summary and summary.messages == rec.stats.messages
    assert by_topic(path)["/pioneer/pose"]


def test_a_failed_disk_is_one_error_and_the_robot_goes_on(pioneer_url: str) -> None:
    disk = StalledDisk()
    rec = Recorder(disk, chunk_seconds=0.05)
    with Pioneer.connect(pioneer_url) as robot:
        rec.add(robot)
        robot.wait_for_sip()
        disk.error = OSError(28, "No space left on device")
        wait_for(lambda: rec.error is not None, what="the write to fail")
        with pytest.raises(RecordingError, match="No space left on device"):
            rec.check()
        sips = robot.stats.sips
        wait_for(lambda: robot.stats.sips >= sips + 3, what="SIPs after the failure")
        wait_for(lambda: rec.stats.dropped > 0, what="listeners dropping quietly")
        assert robot.stats.as_dict()["listener_errors"] == 0
    with pytest.raises(RecordingError, match="last complete chunk"):
        rec.close()
    rec.close()  # idempotent: said once


def test_frames_that_do_not_decode_are_counted_and_kept_raw(tmp_path: Path) -> None:
    path = tmp_path / "bad.mcap"
    with Recorder(path) as rec:
        link = rec.listener("pioneer", "arcos")
        from robocli.io.record.pioneer import PioneerDecoder
        from robocli.robots.pioneer import ROBOT_PARAMS

        link.decoder = PioneerDecoder(rec, "pioneer", ROBOT_PARAMS["p3dx"])
        link("rx", b"\x32\x01", 1.0)  # a SIP far too short for its fields
        link("rx", b"\x32\x01", 1.1)
    assert rec.stats.decode_errors == 2
    raw = by_topic(path)["/pioneer/raw/rx"]
    assert [frame_of(i) for i in raw] == [arcos.frame(b"\x32\x01")] * 2


def test_bad_arguments() -> None:
    with pytest.raises(InvalidArgument):
        Recorder(io.BytesIO(), compression="brotli")
    with pytest.raises(InvalidArgument):
        Recorder(io.BytesIO(), chunk_seconds=0)
    rec = Recorder(io.BytesIO())
    with pytest.raises(InvalidArgument, match="cannot record"):
        rec.add(object())
    rec.close()


def test_a_closed_recorder_never_raises_into_a_device(pioneer_url: str) -> None:
    """A listener still held after the recorder closed (a program that closes the recorder
    first) drops quietly: the robot's reader and keep-alive go on."""
    rec = Recorder(io.BytesIO())
    with Pioneer.connect(pioneer_url) as robot:
        link = rec.listener("pioneer", "arcos")
        robot.add_listener(link)  # held by the device, not detached by the recorder
        rec.close()
        sips = robot.stats.sips
        wait_for(lambda: robot.stats.sips >= sips + 3, what="SIPs after the close")
        assert robot.alive and robot.stats.as_dict()["listener_errors"] == 0
        assert rec.stats.dropped >= 3


def _bytes_read() -> int:
    for line in Path("/proc/self/io").read_text().splitlines():
        if line.startswith("rchar:"):
            return int(line.split()[1])
    raise AssertionError("no rchar in /proc/self/io")


@pytest.mark.skipif(not Path("/proc/self/io").exists(), reason="Linux /proc only")
def test_info_reads_the_summary_not_the_file(tmp_path: Path) -> None:
    import os

    path = tmp_path / "big.mcap"
    blob = os.urandom(100_000)
    with Recorder(path, compression="none") as rec:

        def write(i: int) -> None:
            rec.write(rec.channel("/big", None, encoding="robocli.raw"), blob, 10**18 + i)

        for i in range(500):  # 50 MB
            assert rec.put(write, (i,), 100)
    before = _bytes_read()
    summary = info(path)
    read = _bytes_read() - before
    assert summary.summary and summary.messages == 500 and summary.size > 50_000_000
    assert read < 1_000_000, f"info read {read} bytes of a {summary.size}-byte file"
