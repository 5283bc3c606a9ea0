"""The Hokuyo simulator byte for byte, over real sockets and ptys, with a raw client that is
independent of the robocli client: the golden exchanges of specs/, the statuses of
malformed requests, MD frames and their remaining count, the timer, and the scans of a known
map against the ray-cast truth."""

from __future__ import annotations

import math
import os
import select
import socket
import time
from collections.abc import Iterator

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from robocli.closing import Closing
from robocli.protocols import scip2
from robocli.protocols.scip2.framing import RequestFramer
from robocli.sim.hokuyo import HokuyoSim
from robocli.sim.hokuyo.session import encode_array
from robocli.sim.laser import cast
from robocli.sim.world import World

DEADLINE = 20.0  #: bounds a failure only


class Raw(Closing):
    """A bare SCIP client over a TCP socket or a pty: sends lines, reads reply blocks."""

    def __init__(self, url: str) -> None:
        self.buf = bytearray()
        if url.startswith("tcp://"):
            host, port = url.removeprefix("tcp://").rsplit(":", 1)
            self.sock: socket.socket | None = socket.create_connection((host, int(port)), 5)
            self.fd = self.sock.fileno()
        else:
            import tty

            self.sock = None
            self.fd = os.open(url, os.O_RDWR | os.O_NOCTTY)
            tty.setraw(self.fd)

    def send(self, line: bytes) -> None:
        if self.sock is not None:
            self.sock.sendall(line)
        else:
            os.write(self.fd, line)

    def block(self, timeout: float = DEADLINE) -> bytes:
        end = time.monotonic() + timeout
        while (i := self.buf.find(b"\n\n")) < 0:
            left = end - time.monotonic()
            assert left > 0, f"no reply block; have {bytes(self.buf[:80])!r}"
            if select.select([self.fd], [], [], left)[0]:
                data = os.read(self.fd, 65536)
                assert data, "closed"
                self.buf += data
        out = bytes(self.buf[: i + 2])
        del self.buf[: i + 2]
        return out

    def ask(self, line: bytes) -> bytes:
        self.send(line)
        return self.block()

    def close(self) -> None:
        if self.sock is not None:
            self.sock.close()
        else:
            os.close(self.fd)


@pytest.fixture(params=["tcp", "pty"])
def urg(request: pytest.FixtureRequest) -> Iterator[tuple[HokuyoSim, Raw]]:
    with HokuyoSim("urg-04lx", time_scale=4.0) as sim:
        url = sim.serve_tcp() if request.param == "tcp" else sim.serve_pty()
        with Raw(url) as raw:
            yield sim, raw


def test_urg_boots_in_scip11_and_switches(urg: tuple[HokuyoSim, Raw]) -> None:
    sim, raw = urg
    assert raw.ask(b"QT\n") == b"QT\nE\n\n"  # how urg_library recognises SCIP 1.1
    assert raw.ask(b"SCIP2.0\n") == b"SCIP2.0\n0\n\n"  # G10
    assert raw.ask(b"QT\n") == b"QT\n00P\n\n"  # G5
    assert raw.ask(b"SCIP2.0\n") == b"SCIP2.0\n0\n\n"  # in 2.0 as well


def test_golden_exchanges(urg: tuple[HokuyoSim, Raw]) -> None:
    sim, raw = urg
    raw.ask(b"SCIP2.0\n")
    assert raw.ask(b"VV\n") == (  # G1
        b"VV\n00P\nVEND:Hokuyo Automatic Co.,Ltd.;[\nPROD:SOKUIKI Sensor URG-04LX;[\n"
        b"FIRM:3.1.00(18/Jan./2007);`\nPROT:SCIP 2.0;N\nSERI:H0614967;V\n\n"
    )
    assert raw.ask(b"PP\n") == (  # G2
        b"PP\n00P\nMODL:URG-04LX(Hokuyo Automatic Co.,Ltd.);N\nDMIN:20;4\nDMAX:5600;_\n"
        b"ARES:1024;\\\nAMIN:44;7\nAMAX:725;o\nAFRT:384;6\nSCAN:600;e\n\n"
    )
    assert raw.ask(b"GD0044072501\n") == b"GD0044072501\n10Q\n\n"  # G6: laser off
    assert raw.ask(b"BM\n") == b"BM\n00P\n\n"  # G3
    assert raw.ask(b"BM\n") == b"BM\n02R\n\n"
    assert raw.ask(b"QT\n") == b"QT\n00P\n\n"
    assert raw.ask(b"BM;abc\n") == b"BM;abc\n00P\n\n"  # G4
    assert raw.ask(b"XX\n") == b"XX\n0Ee\n\n"  # G7
    assert raw.ask(b"TM0\n") == b"TM0\n00P\n\n"  # G9
    tm1 = raw.ask(b"TM1\n")
    assert tm1[:8] == b"TM1\n00P\n" and len(tm1) == 15 and tm1.endswith(b"\n\n")
    scip2.check_line(tm1[8:13])
    assert raw.ask(b"QT\n") == b"QT\n0Ee\n\n"  # refused in time-adjust mode (urg_library)
    assert raw.ask(b"TM2\n") == b"TM2\n00P\n\n"
    assert raw.ask(b"TM2\n") == b"TM2\n03S\n\n"


@pytest.mark.parametrize(
    ("line", "status"),
    [
        (b"GD004407250", "0C"), (b"GD00440725011", "0D"), (b"GDx044072501", "01"),
        (b"GD0044x72501", "02"), (b"GD00440725x1", "03"), (b"GD0044072601", "04"),
        (b"GD0400030001", "05"), (b"MD004407250110x", "07"), (b"MD0044072501x00", "06"),
        (b"ME0044072501000", "0E"), (b"GE0044072501", "0E"), (b"RT", "0E"), (b"VVV", "0D"),
        (b"TM", "0C"), (b"TM7", "01"), (b"TM1", "04"), (b"BM;" + b"a" * 17, "0G"),
        (b"BM;a!", "0H"), (b"ND0044072501000", "0E"), (b"TM2", "03"),
    ],
)  # fmt: skip
def test_bad_requests_get_the_device_statuses(line: bytes, status: str) -> None:
    with HokuyoSim("urg-04lx", scip11=False) as sim:
        with Raw(sim.serve_tcp()) as raw:
            reply = raw.ask(line + b"\n")
    assert reply == line + b"\n" + scip2.with_sum(status.encode()) + b"\n"


def test_terminators_and_empty_lines() -> None:
    framer = RequestFramer()
    assert framer.feed(b"VV\r\nPP\rII\n\n\r\nBM") == [b"VV", b"PP", b"II"]
    assert framer.feed(b"\r") == [b"BM"]
    assert framer.feed(b"\nQT\n") == [b"QT"]  # the LF of a CR LF split across reads
    assert framer.feed(b"x" * 100 + b"\nQT\n") == [b"QT"]  # an over-long line is dropped
    assert framer.stats.bad_lengths == 1 and framer.stats.dropped_bytes == 100


def test_encode_array_matches_the_reference() -> None:
    values = [0, 1, 63, 64, 1000, 4095, 5432, 262143]
    assert encode_array(np.array(values), 3) == scip2.encode_values(values, 3)
    assert encode_array(np.array([1234, 4095]), 2) == b"CBoo"


def _scan_values(block: bytes) -> tuple[int, list[int]]:
    s = scip2.decode_scan(block)
    return s.timestamp, [int(v) for v in s.ranges]


def test_md_frames_count_down_and_switch_the_laser_off() -> None:
    with HokuyoSim("utm-30lx", time_scale=4.0) as sim:
        with Raw(sim.serve_tcp()) as raw:
            assert raw.ask(b"MD0000108001003;tag\n") == b"MD0000108001003;tag\n00P\n\n"
            frames = [raw.block() for _ in range(3)]
            assert raw.ask(b"GD0000108001\n") == b"GD0000108001\n10Q\n\n"  # laser off after N
    echoes = [f.split(b"\n", 1)[0] for f in frames]
    assert echoes == [b"MD0000108001002;tag", b"MD0000108001001;tag", b"MD0000108001000;tag"]
    stamps = [scip2.decode_scan(f).timestamp for f in frames]
    assert all(b - a == 25 for a, b in zip(stamps, stamps[1:], strict=False))  # 2400 rpm
    assert all(len(scip2.decode_scan(f).ranges) == 1081 for f in frames)


def test_md_interval_skips_scans_and_qt_stops() -> None:
    with HokuyoSim("ust-10lx", time_scale=4.0) as sim:
        with Raw(sim.serve_tcp()) as raw:
            raw.ask(b"MS0000108010200\n")  # cluster 10, every 3rd scan, until QT
            frames = [raw.block() for _ in range(3)]
            raw.send(b"QT\n")
            while (b := raw.block()) != b"QT\n00P\n\n":  # frames already queued come first
                assert b.startswith(b"MS")
    stamps = [scip2.decode_scan(f).timestamp for f in frames]
    assert [b - a for a, b in zip(stamps, stamps[1:], strict=False)] == [75, 75]
    assert all(f.startswith(b"MS0000108010200\n99b\n") for f in frames)
    assert len(scip2.decode_scan(frames[0]).ranges) == 109


def test_timer_wraps_at_24_bits_and_rs_resets_it() -> None:
    start = (1 << 24) - 60
    with HokuyoSim("utm-30lx", time_scale=1.0, timer_start_ms=start) as sim:
        with Raw(sim.serve_tcp()) as raw:
            raw.ask(b"MD0540054001000\n")
            stamps = [scip2.decode_scan(raw.block()).timestamp for _ in range(6)]
            raw.ask(b"QT\n")
            raw.ask(b"RS\n")
            raw.ask(b"TM0\n")
            after = scip2.decode_value(raw.ask(b"TM1\n")[8:12])
    assert stamps[-1] < stamps[0]  # wrapped
    unwrapped = [s if s >= stamps[0] else s + (1 << 24) for s in stamps]
    assert all(b - a == 25 for a, b in zip(unwrapped, unwrapped[1:], strict=False))
    assert after < 10_000


def test_scans_of_a_known_map_match_the_ray_cast_truth() -> None:
    walls = [(-2.0, -3.0, 4.0, -3.0), (4.0, -3.0, 4.0, 2.5), (4.0, 2.5, -2.0, 2.5),
             (1.0, 0.5, 1.5, 1.0)]  # fmt: skip
    world = World.from_segments(walls)
    pose = (0.3, -0.2, 0.4)
    with HokuyoSim("utm-30lx", world=world, pose=pose, time_scale=4.0) as sim:
        with Raw(sim.serve_tcp()) as raw:
            raw.ask(b"BM\n")
            _, values = _scan_values(raw.ask(b"GD0000108001\n"))
    angles = (np.arange(1081) - 540) * 2 * math.pi / 1440
    truth = cast(world, pose, angles, math.inf) * 1000.0
    got = np.array(values, dtype=np.float64)
    hit = np.isfinite(truth) & (truth <= 60000)
    assert hit.sum() > 700
    assert np.all(np.abs(got[hit] - truth[hit]) <= 0.5 + 1e-6)  # the device's 1 mm
    assert np.all(got[~hit] == 1)  # no return: UTM code 1


def test_cluster_takes_the_group_minimum_ignoring_codes() -> None:
    world = World.from_segments([(1.0, -5.0, 1.0, 5.0)])  # a wall 1 m ahead, nothing behind
    with HokuyoSim("utm-30lx", world=world, time_scale=4.0) as sim:
        with Raw(sim.serve_tcp()) as raw:
            raw.ask(b"BM\n")
            _, single = _scan_values(raw.ask(b"GD0000108001\n"))
            _, grouped = _scan_values(raw.ask(b"GD0000108007\n"))
    for g, v in enumerate(grouped):
        group = single[g * 7 : g * 7 + 7]
        valid = [x for x in group if x >= 23]
        assert v == (min(valid) if valid else group[0])


def test_second_tcp_client_is_refused_and_a_new_one_finds_it_idle() -> None:
    with HokuyoSim("ust-10lx", time_scale=4.0) as sim:
        url = sim.serve_tcp()
        first = Raw(url)
        first.ask(b"MD0000108001000\n")
        first.block()
        second = socket.create_connection(first.sock.getpeername(), 5)  # type: ignore[union-attr]
        second.settimeout(DEADLINE)
        assert b"busy" in second.recv(256)
        second.close()
        first.close()
        assert sim.server is not None
        end = time.monotonic() + DEADLINE
        while sim.server.links() and time.monotonic() < end:
            sim.server.reap(0.1)
        with Raw(url) as third:
            assert third.ask(b"GD0000108001\n") == b"GD0000108001\n10Q\n\n"  # idle, laser off


def test_rs_ss_cr_hs_rb_as_the_device_answers() -> None:
    with HokuyoSim("urg-04lx", time_scale=4.0) as sim:
        with Raw(sim.serve_pty()) as pty:
            assert pty.ask(b"SCIP2.0\n") == b"SCIP2.0\n0\n\n"
            assert pty.ask(b"SS115200\n") == b"SS115200\n00P\n\n"  # USB: taken, no effect
            assert pty.ask(b"CR05\n") == b"CR05\n00P\n\n"
            assert pty.ask(b"CR50\n") == b"CR50\n02R\n\n"
            assert pty.ask(b"HS1\n") == b"HS1\n00P\n\n"
            assert pty.ask(b"HS1\n") == b"HS1\n02R\n\n"
            assert pty.ask(b"BM\n") == b"BM\n00P\n\n"
            assert pty.ask(b"RS\n") == b"RS\n00P\n\n"  # laser off, timer 0
            assert pty.ask(b"GD0044072501\n") == b"GD0044072501\n10Q\n\n"
            assert pty.ask(b"RB\n") == b"RB\n01Q\n\n"  # armed
            assert pty.ask(b"RB\n") == b"RB\n00P\n\n"  # reboot: back to SCIP 1.1
            assert pty.ask(b"VV\n") == b"VV\nE\n\n"
    with HokuyoSim("ust-10lx") as sim:
        with Raw(sim.serve_tcp()) as tcp:
            assert tcp.ask(b"SS115200\n") == b"SS115200\n0Ff\n\n"  # no bit rate on Ethernet
            assert tcp.ask(b"CR05\n") == b"CR05\n04T\n\n"  # not supported
            assert tcp.ask(b"RT\n") == b"RT\n00P\n\n"


@given(st.lists(st.integers(0, (1 << 18) - 1), max_size=300), st.sampled_from([2, 3, 4]))
def test_encode_array_equals_the_reference(values: list[int], width: int) -> None:
    values = [v & ((1 << (6 * width)) - 1) for v in values]
    got = encode_array(np.array(values, dtype=np.int64).reshape(-1), width)
    assert got == scip2.encode_values(values, width)


def test_a_late_tick_sends_no_more_frames_than_the_count() -> None:
    """A tick that finds five scans due (the machine stalled) while MD asked for two sends
    the two, counting 01 then 00, and stops: no frame beyond the count."""
    with HokuyoSim("utm-30lx", time_scale=0.1) as sim:  # ticks 250 ms apart: none in the way
        with Raw(sim.serve_tcp()) as raw:
            raw.ask(b"MD0000001001002\n")
            (session,) = sim.sessions()
            session.on_scans(sim.latest_scan() + 6)  # the late tick
            frames = [raw.block() for _ in range(2)]
            assert raw.ask(b"QT\n") == b"QT\n00P\n\n"  # nothing queued in between
    assert [f.split(b"\n", 1)[0] for f in frames] == [b"MD0000001001001", b"MD0000001001000"]
