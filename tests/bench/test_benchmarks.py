"""`robocli bench` parts: statistics on inputs with known answers, the C peers (ping-pong,
ARCOS responder) over real sockets, the client against the responder. No wall-clock asserts."""

from __future__ import annotations

import socket
import subprocess
import sys

import numpy as np
import pytest

from robocli.bench.harness import allowed_cpus, c_floor
from robocli.bench.pioneer import (
    arcos_responder,
    arcos_responder_table,
    pioneer_on_responder,
    pioneer_rtt,
)
from robocli.bench.stats import Run, SampleStats, histogram, report
from robocli.core import PingPong, Responder, pin_supported
from robocli.errors import TransportError
from robocli.protocols import arcos


def test_stats_of_known_samples() -> None:
    s = SampleStats.of([1.0, 2.0, 3.0, 4.0, 5.0])
    assert (s.n, s.mean, s.median, s.min, s.max) == (5, 3.0, 3.0, 1.0, 5.0)
    assert s.std == pytest.approx(np.sqrt(2.5))  # sample standard deviation
    assert s.p90 == pytest.approx(4.6) and s.p99 == pytest.approx(4.96)


def test_stats_single_sample_and_empty() -> None:
    assert SampleStats.of([7.0]).std == 0.0
    with pytest.raises(ValueError):
        SampleStats.of([])


def test_report_scales_to_microseconds_and_floor_multiples() -> None:
    floor = SampleStats.of([10e-6] * 3)
    r = report("x", [20e-6, 40e-6, 60e-6], floor)
    assert r["median"] == pytest.approx(40.0) and r["n"] == 3
    assert r["x_floor_median"] == pytest.approx(4.0)


def test_histogram_counts_every_sample() -> None:
    samples = np.array([1, 1, 2, 3, 3, 3, 10], dtype=float) * 1e-6
    lines = histogram(samples, bins=3)
    assert len(lines) == 3
    assert sum(int(line.split()[4]) for line in lines) == 7
    assert histogram([]) == []
    assert len(histogram([5e-6, 5e-6], bins=2)) == 2  # all equal: still a valid range


# ---------------------------------------------------------------------------- C peers


def _recv_frames(sock: socket.socket, count: int) -> list[bytes]:
    """Read exactly ``count`` ARCOS frames (the socket has a timeout: a missing one fails)."""
    buf = b""
    frames: list[bytes] = []
    while len(frames) < count:
        chunk = sock.recv(4096)
        assert chunk, "responder closed the connection"
        buf += chunk
        while len(buf) >= 3 and len(buf) >= buf[2] + 3:
            frames.append(buf[: buf[2] + 3])
            buf = buf[buf[2] + 3 :]
    assert buf == b""
    return frames


def test_responder_answers_table_frames_only() -> None:
    table = {b"\x00": arcos.frame(b"\x00"), b"\x01": arcos.frame(b"\x01") + arcos.frame(b"\x02")}
    with (
        Responder(table) as responder,
        socket.create_connection(("127.0.0.1", responder.port), timeout=5) as sock,
    ):
        # garbage, a frame not in the table, a table frame split in two writes
        sock.sendall(b"\x55\xfa" + arcos.encode_command(arcos.Command.ENABLE, 1))
        sync1 = arcos.encode_command(1)
        sock.sendall(sync1[:2])
        sock.sendall(sync1[2:] + arcos.encode_command(0))
        frames = _recv_frames(sock, 3)
        assert [arcos.unframe(f) for f in frames] == [b"\x01", b"\x02", b"\x00"]
        stats = responder.stats
        assert (stats.connections, stats.frames, stats.replies) == (1, 3, 2)
    responder.close()  # idempotent


def test_responder_serves_the_next_client_and_stops_while_a_peer_does_not_read() -> None:
    with Responder({b"\x00": arcos.frame(b"\x00")}) as responder:
        with socket.create_connection(("127.0.0.1", responder.port), timeout=5) as first:
            first.sendall(arcos.encode_command(0))
            assert _recv_frames(first, 1) == [arcos.frame(b"\x00")]
        with socket.create_connection(("127.0.0.1", responder.port), timeout=5) as second:
            second.sendall(arcos.encode_command(0))
            assert _recv_frames(second, 1) == [arcos.frame(b"\x00")]
            # a peer that floods requests and never reads: the responder blocks in send,
            # and close() must still return (the pytest timeout bounds it)
            second.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            second.settimeout(0.5)
            with pytest.raises(OSError):
                for _ in range(200_000):
                    second.sendall(arcos.encode_command(0) * 64)
            responder.close()


def test_responder_rejects_bad_tables() -> None:
    with pytest.raises(ValueError):
        Responder({b"": b"x"})
    with pytest.raises(ValueError):
        Responder({b"\x00": b"x" * 5000})
    with pytest.raises(ValueError):
        Responder({bytes((i, j)): b"" for i in range(2) for j in range(256)})


def test_responder_table_frames_decode() -> None:
    table = arcos_responder_table(name="bench", subtype="p3dx")
    replies = {key: arcos.unframe(reply) for key, reply in table.items()}
    _, sync2 = arcos.decode_server(replies[b"\x02"])
    assert (sync2.name, sync2.type, sync2.subtype) == ("bench", "Pioneer", "p3dx")
    open_key = arcos.encode_command(arcos.Command.OPEN, 1)[3:-2]
    config_key = arcos.encode_command(arcos.Command.CONFIG, 1)[3:-2]
    assert replies[open_key][0] == arcos.PacketType.SIP
    ptype, config = arcos.decode_server(replies[config_key])
    assert ptype == arcos.PacketType.CONFIG and config.name == "bench"


@pytest.mark.timeout(30)
def test_client_handshake_and_config_round_trips_against_the_responder() -> None:
    with arcos_responder() as responder:
        with pioneer_on_responder(responder) as robot:
            assert robot.identity.subtype == "p3dx"
            run = pioneer_rtt(robot, Run("rtt", 50), warmup=2)
            assert run.complete and (run.values > 0).all()
            assert robot.config is not None and robot.config["name"] == "robocli-bench"
        assert responder.stats.replies >= 3 + 1 + 52  # SYNC0-2, OPEN, CONFIG requests


def test_pingpong_runs_in_chunks_on_one_connection() -> None:
    cpus = allowed_cpus()
    cpu = cpus[0] if cpus else None
    with PingPong(16, echo_cpu=cpu) as pp:
        a, b = pp.run(100, cpu), pp.run(50, cpu)
    assert a.shape == (100,) and b.shape == (50,)
    assert (a > 0).all() and (b > 0).all()
    with pytest.raises(TransportError):
        pp.run(1)
    run = c_floor(Run("floor", 1234), cpu, cpu)
    assert run.complete and (run.values > 0).all()


@pytest.mark.skipif(not pin_supported(), reason="threads cannot be pinned here")
def test_pingpong_refuses_a_cpu_it_cannot_use() -> None:
    with PingPong(16) as pp, pytest.raises(ValueError):
        pp.run(10, cpu=1000)
    with pytest.raises(ValueError):
        PingPong(16, echo_cpu=-1)


def test_run_keeps_partial_samples() -> None:
    run = Run("x", 10)
    run.samples[:3] = [1.0, 2.0, 3.0]
    run.count = 3
    assert list(run.values) == [1.0, 2.0, 3.0] and not run.complete
    r = report("x", run.values, SampleStats.of([1.0]), targets=(3.0, 6.0))
    assert r["target_met"] is True
    r = report("x", run.values, SampleStats.of([0.5]), targets=(3.0, 6.0))
    assert r["target_met"] is False  # p99 2.98 / 0.5 = 5.96 x, median 4 x > 3 x


def test_importing_the_client_does_not_import_numpy() -> None:
    code = "import sys, robocli.devices.pioneer; assert 'numpy' not in sys.modules, 'numpy'"
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)
