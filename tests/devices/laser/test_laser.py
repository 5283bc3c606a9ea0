"""The Laser client against the Hokuyo simulator over real ptys and TCP sockets, for each
model; and its failures: garbage, a truncated block, a wrong checksum, a sensor that stops
answering, a sensor still streaming MD for a client that died. Each gives a typed error, or a
resync with a count, never a hang."""

from __future__ import annotations

import math
import subprocess
import sys
import time
from typing import Any

import numpy as np
import pytest

from robocli import Laser
from robocli.errors import (
    ChecksumError,
    ConnectionLost,
    DeviceError,
    FramingError,
    RobocliError,
    TimeoutError,
)
from robocli.protocols import scip2
from robocli.sim.hokuyo import HokuyoSim
from tests.waiting import wait_for

DEADLINE = 20.0  #: bounds a failure only
MODELS = ["urg-04lx", "utm-30lx", "ust-10lx"]


@pytest.fixture(params=["tcp", "pty"])
def link(request: pytest.FixtureRequest) -> str:
    return str(request.param)


def _serve(sim: HokuyoSim, link: str) -> str:
    return sim.serve_tcp() if link == "tcp" else sim.serve_pty()


@pytest.mark.parametrize("model", MODELS)
def test_connect_scan_and_stream_each_model(model: str, link: str) -> None:
    with HokuyoSim(model, time_scale=4.0) as sim:
        url = _serve(sim, link)
        with Laser.connect(url, timeout=5.0) as laser:
            info = laser.info
            assert info is not None and info.model == sim.model.modl
            assert laser.switched == (model == "urg-04lx")  # the URG boots in SCIP 1.1
            assert info.vv["PROT"] == "SCIP 2.0"
            scan = laser.scan()
            n = sim.model.amax - sim.model.amin + 1
            assert scan.ranges.shape == scan.angles.shape == (n,)
            assert scan.ranges.dtype == np.float64
            assert scan.angles[0] == pytest.approx(info.angle(info.amin))
            assert scan.angles[-1] == pytest.approx(info.angle(info.amax))
            nan = np.isnan(scan.ranges)
            assert np.all(scan.codes[nan] < info.dmin) and np.all(scan.codes[~nan] == 0)
            intensity = model != "urg-04lx"
            got = list(laser.scans(count=3, cluster=2, intensity=intensity))
            assert [s.remaining for s in got] == [2, 1, 0]
            assert all(len(s.ranges) == math.ceil(n / 2) for s in got)
            assert all((s.intensities is not None) == intensity for s in got)
            stamps = [s.stamp_ms for s in got]
            assert all(
                b - a == round(info.period * 1000) for a, b in zip(stamps, stamps[1:], strict=False)
            )
            assert laser.dropped == 0
        session = wait_for(lambda: sim.sessions() or [None], "session")[0]
        if session is not None:  # pty: the session lives on; close() sent QT
            wait_for(lambda: session.stream is None and not session.laser, "QT handled")


def test_close_always_sends_qt_and_stops_a_stream() -> None:
    with HokuyoSim("urg-04lx", time_scale=4.0) as sim:
        path = sim.serve_pty()
        laser = Laser.connect(path)
        laser.start()
        laser.read()
        (session,) = sim.sessions()
        assert session.stream is not None
        laser.close()
        wait_for(lambda: session.stream is None and not session.laser, "QT handled")
        laser.close()  # idempotent


def test_scan_time_maps_the_sensor_clock_to_the_host() -> None:
    with HokuyoSim("utm-30lx", time_scale=1.0) as sim:
        with Laser.connect(sim.serve_tcp()) as laser:
            assert laser.clock.offset is not None
            scans = list(laser.scans(count=20))
            for s in scans:
                # step 0 is measured one scan before the frame can be sent
                assert s.t <= s.received + 0.005
                assert s.received - s.t < 1.0
            ts = [s.t for s in scans]
            assert all(
                b - a == pytest.approx(0.025, abs=1e-6) for a, b in zip(ts, ts[1:], strict=False)
            )


def test_clock_unwraps_the_24_bit_stamp() -> None:
    # the wrap 1 s after the simulator starts its timer (time_scale 4: 250 ms of wall time),
    # so that a connect slowed by a loaded machine still sees scans from before it
    with HokuyoSim("utm-30lx", time_scale=4.0, timer_start_ms=(1 << 24) - 1000) as sim:
        with Laser.connect(sim.serve_tcp(), sync_samples=0) as laser:
            scans = list(laser.scans(count=60))
    stamps = [s.stamp_ms for s in scans]
    assert stamps[0] < 1 << 24  # the first scan before the wrap
    assert stamps[-1] > 1 << 24  # past the wrap, unwrapped
    assert all(b - a == 25 for a, b in zip(stamps, stamps[1:], strict=False))
    assert laser.clock.wraps == 1


def test_garbage_between_frames_is_skipped_and_counted() -> None:
    with HokuyoSim("utm-30lx", time_scale=4.0) as sim:
        with Laser.connect(sim.serve_tcp()) as laser:
            laser.start(start=500, end=580)
            laser.read()
            sim.inject(b"\x00\xff garbage \x13\nnot a reply\n\n")
            before = laser.frames
            wait_for(lambda: laser.frames >= before + 3, "frames after the garbage")
            assert laser.session.stats.dropped_bytes > 0
            laser.stop()
            assert laser.scan().ranges.size == 1081  # requests still work


def _frame(start: int, end: int, ts: int) -> bytes:
    values = [1000 + i for i in range(end - start + 1)]
    echo = b"MD%04d%04d01000" % (start, end)
    return scip2.build_scan(echo, "99", ts, values)


def test_wrong_checksum_and_truncated_frames_are_dropped_and_counted() -> None:
    with HokuyoSim("utm-30lx", time_scale=4.0) as sim:
        with Laser.connect(sim.serve_tcp()) as laser:
            laser.start(start=0, end=200)
            laser.read()
            good = _frame(0, 200, 5)
            lines = good.split(b"\n")
            bad_sum = b"\n".join([*lines[:3], lines[3][:-1] + b"!", *lines[4:]])
            truncated = b"\n".join(lines[:4]) + b"\n\n"
            sim.inject(bad_sum + truncated)
            wait_for(lambda: laser.dropped >= 2, "the two bad frames counted")
            before = laser.frames
            wait_for(lambda: laser.frames > before, "good frames after them")


def test_bad_reply_to_a_request_is_a_typed_error() -> None:
    with HokuyoSim("utm-30lx", time_scale=4.0) as sim:
        with Laser.connect(sim.serve_tcp()) as laser:
            sim.mute = True  # the simulator stays silent: the test answers in its place
            line = b"GD0000010001\n"
            reply = scip2.build_scan(line[:-1], "00", 7, [1000] * 11)
            bad = reply.replace(b"\n00P\n", b"\n00P\n", 1)[:-10] + b"?" + reply[-9:]
            sim.inject(bad)
            with pytest.raises((ChecksumError, FramingError)):
                laser._to_scan(  # what scan() does with the reply it matched
                    scip2.decode_scan(laser._request_block(line, 5.0)), 0.0, observe=False
                )


def test_a_sensor_that_stops_answering_times_out() -> None:
    with HokuyoSim("ust-10lx", time_scale=4.0) as sim:
        laser = Laser.connect(sim.serve_tcp(), timeout=0.5)
        try:
            laser.start()
            laser.read()
            sim.mute = True
            with pytest.raises(TimeoutError):
                while True:
                    laser.read(timeout=1.0)
            with pytest.raises(TimeoutError):
                laser.scan()
        finally:
            t = time.monotonic()
            laser.close()
            assert time.monotonic() - t < DEADLINE


def test_nothing_answering_at_all_is_a_timeout_at_connect() -> None:
    with HokuyoSim("ust-10lx") as sim:
        sim.mute = True
        with pytest.raises(TimeoutError, match="no SCIP sensor answered"):
            Laser.connect(sim.serve_tcp(), timeout=0.5)


def test_connect_to_a_sensor_still_streaming_for_a_dead_client() -> None:
    """A process streaming MD over the pty is killed (no QT): the sensor goes on sending
    frames; the next client stops it, skips the stale frames, and works."""
    with HokuyoSim("urg-04lx", time_scale=4.0) as sim:
        path = sim.serve_pty()
        code = (
            "import sys, os\n"
            "from robocli import Laser\n"
            "laser = Laser.connect(sys.argv[1], sync_samples=0)\n"
            "laser.start()\n"
            "laser.read()\n"
            "print('streaming', flush=True)\n"
            "os.kill(os.getpid(), 9)\n"
        )
        proc = subprocess.run(
            [sys.executable, "-c", code, path], capture_output=True, text=True, timeout=60
        )
        assert "streaming" in proc.stdout and proc.returncode == -9
        (session,) = sim.sessions()
        assert session.stream is not None  # nobody said QT
        with Laser.connect(path) as laser:
            assert session.stream is None
            assert laser.scan().ranges.size == 682
            frames = list(laser.scans(count=2))
            assert [f.remaining for f in frames] == [1, 0]


def test_a_listener_that_raises_does_not_stop_the_stream() -> None:
    with HokuyoSim("utm-30lx", time_scale=4.0) as sim:
        with Laser.connect(sim.serve_tcp()) as laser:
            seen: list[int] = []

            def bad(scan: Any) -> None:
                seen.append(scan.stamp_ms)
                raise RuntimeError("listener bug")

            laser.add_listener(bad, kind="scans")
            for _ in laser.scans(count=4, start=0, end=100):
                pass
            assert len(seen) == 4
            assert laser.session.stats.listener_errors == 4


def test_refusals_raise_the_sensor_status() -> None:
    with HokuyoSim("urg-04lx", time_scale=4.0) as sim:
        with Laser.connect(sim.serve_tcp(), laser_on=False) as laser:
            with pytest.raises(scip2.ScipStatusError) as err:
                laser.command("GD", start=44, end=725, cluster=1)
            assert err.value.status == "10"
            with pytest.raises(scip2.ScipStatusError) as err:
                laser.scan(intensity=True)  # no GE on a URG-04LX
            assert err.value.status == "0E"
            with pytest.raises(RobocliError):
                laser.scan(start=0, end=800)
            assert laser.scan(start=0, end=50).codes[:44].tolist() == [19] * 44


def test_unlimited_stream_over_pty_at_eight_times_real_time() -> None:
    """ME frames of 6.7 kB at 320 a second: a client falling behind on a pty may lose
    frames, dropped whole by the simulator (never cut) and counted: every scan it yields is
    whole and in order, none failed to decode."""
    with HokuyoSim("utm-30lx", time_scale=8.0) as sim:
        with Laser.connect(sim.serve_pty()) as laser:
            it = laser.scans(intensity=True)
            got = [next(it) for _ in range(30)]
            it.close()
            assert not laser.streaming
            stamps = [s.stamp_ms for s in got]
            assert stamps == sorted(set(stamps))
            assert all(s.ranges.size == 1081 and s.intensities is not None for s in got)
            (session,) = sim.sessions()
            missing = sum((b - a) // 25 - 1 for a, b in zip(stamps, stamps[1:], strict=False))
            # a lost frame was dropped whole by the simulator, or by the client's queue
            assert laser.dropped == 0  # nothing arrived cut
            assert missing == 0 or laser.overrun + session.frames_dropped > 0


def test_the_offset_follows_a_drifting_sensor_clock() -> None:
    """A sensor clock 2 % fast: over 4 s of streaming it gains 80 ms on the host. Mapped
    with the offset of the connect-time TM calibration only, step 0 of the last scans would
    lie ~80 ms after their reception; the offset kept up to date from the stream keeps them
    where the first ones were."""
    with HokuyoSim("utm-30lx", time_scale=1.0, drift_ppm=20_000) as sim:
        with Laser.connect(sim.serve_tcp()) as laser:
            calibrated = laser.clock.offset
            assert calibrated is not None
            scans = list(laser.scans(count=160))
    # the smallest delay of a run of frames: a loaded machine only adds to a frame's delay
    early = min(s.received - s.t for s in scans[:8])  # what the latency was taken from
    late = min(s.received - s.t for s in scans[-30:])
    stale = min(s.received - (calibrated + s.stamp_ms / 1000) for s in scans[-30:])
    assert stale < early - 0.05  # the calibration alone drifts by ~75 ms between the runs
    assert abs(late - early) < 0.025


def test_a_pyserial_url_reaches_the_sensor() -> None:
    with HokuyoSim("ust-10lx", time_scale=4.0) as sim:
        url = sim.serve_tcp().replace("tcp://", "socket://")
        with Laser.connect(url) as laser:
            assert laser.url.startswith("socket://")
            assert laser.scan().ranges.size == 1081
            assert [s.remaining for s in laser.scans(count=2)] == [1, 0]


def test_a_second_client_is_told_busy_not_link_lost() -> None:
    """The simulator serves one client and refuses the next with a line, then closes: the
    client reads that line (its handshake runs before the reader thread takes the link)
    and raises DeviceError (exit 4), not ConnectionLost (exit 1)."""
    with HokuyoSim("ust-10lx", time_scale=4.0) as sim:
        url = sim.serve_tcp()
        with Laser.connect(url, sync_samples=0) as first:
            with pytest.raises(DeviceError, match="laser busy: another client holds it") as err:
                Laser.connect(url, timeout=5.0)
            assert not isinstance(err.value, ConnectionLost)
            assert first.scan().ranges.size == 1081  # the first client is undisturbed
