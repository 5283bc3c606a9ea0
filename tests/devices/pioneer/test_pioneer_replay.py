"""The client against recorded robot traffic: a scripted server replays what AMRISim sent
(handshake and CONFIG replies on request, then every recorded SIP) over a real socket."""

from __future__ import annotations

import math
import re
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from robocli.core import Framer
from robocli.devices.pioneer import Pioneer
from robocli.io.capture import read_capture
from robocli.protocols import arcos
from tests import paths
from tests.waiting import wait_for

DATA = paths.DATA / "arcos"


def frames_from(conn: socket.socket) -> Iterator[bytes]:
    """The ARCOS frames ``conn`` brings, in order, until its peer closes it."""
    framer = Framer("arcos")
    while data := conn.recv(4096):
        yield from framer.feed(data)


class ReplayServer:
    """Answers SYNC0/1/2 and CONFIG with the next recorded non-SIP frame; after OPEN and
    CONFIG streams the recorded SIPs back to back (1 ms apart)."""

    def __init__(self, trace: Path) -> None:
        frames = [f.frame for f in read_capture(trace) if f.direction == "rx"]
        self.replies = [f for f in frames if f[3] in (0, 1, 2, arcos.PacketType.CONFIG)]
        self.sips = [f for f in frames if f[3] == arcos.PacketType.SIP]
        self.received: list[int] = []
        self.srv = socket.create_server(("127.0.0.1", 0))
        self.url = f"tcp://127.0.0.1:{self.srv.getsockname()[1]}"
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        conn, _ = self.srv.accept()
        replies = list(self.replies)
        streaming = False
        with conn:
            for frame in frames_from(conn):
                cmd = frame[3]
                self.received.append(cmd)
                if cmd in (0, 1, 2, arcos.Command.CONFIG) and not streaming and replies:
                    if cmd == arcos.Command.CONFIG or replies[0][3] == cmd:
                        conn.sendall(replies.pop(0))
                if cmd == arcos.Command.CONFIG and not streaming:
                    streaming = True
                    threading.Thread(target=self._stream, args=(conn,), daemon=True).start()

    def _stream(self, conn: socket.socket) -> None:
        for sip in self.sips:
            conn.sendall(sip)
            time.sleep(0.001)


def _last_summary_sip(trace: Path) -> tuple[int, int, float]:
    text = trace.with_suffix(".txt").read_text()
    m = list(re.finditer(r"SIP .* x=(\d+)\(.* y=(\d+)\(.* th=-?\d+\((-?[\d.]+)deg\)", text))[-1]
    return int(m[1]), int(m[2]), float(m[3])


@pytest.mark.parametrize("stem", ["a_simpleConnect", "b_simpleMotionCommands", "c2_wander"])
def test_client_decodes_recorded_session(stem: str) -> None:
    trace = DATA / f"{stem}.jsonl"
    server = ReplayServer(trace)
    with Pioneer.connect(server.url, sip_timeout=3.0) as robot:
        assert robot.identity == arcos_identity("AMRISim", "Pioneer", "p3dx")
        assert robot.params.subtype == "p3dx"
        assert robot.config is not None and robot.config["watchdog"] == 2000
        deadline = time.monotonic() + 10
        while robot.stats.sips < len(server.sips) and time.monotonic() < deadline:
            robot.wait_for_sip(timeout=10)
        state = robot.state
        assert robot.stats.sips == len(server.sips)
        assert robot.stats.bad_checksums == 0 and robot.stats.dropped_bytes == 0
    x_raw, y_raw, th_deg = _last_summary_sip(trace)
    # the 15-bit counters never wrapped in these sessions: small negatives show as 32768 - k
    unwrap = [v - 0x8000 if v > 0x4000 else v for v in (x_raw, y_raw)]
    assert state.x == pytest.approx(unwrap[0] * 0.485 / 1000, abs=1e-9)
    assert state.y == pytest.approx(unwrap[1] * 0.485 / 1000, abs=1e-9)
    assert math.degrees(state.th) == pytest.approx(th_deg, abs=0.01)
    assert state.battery == pytest.approx(13.0)
    assert state.state_of_charge is None  # AMRISim sends 0: not modelled, as ARIA reads it
    assert state.sonar[:16] == pytest.approx([5.0] * 16) or not state.sonar_enabled
    # the client closed the session as ARIA does: stop, motors off, CLOSE
    # the server reads them in its own thread
    wait_for(lambda: server.received[-1:] == [arcos.Command.CLOSE], "the client's CLOSE")
    assert server.received[-4:] == [
        arcos.Command.VEL,
        arcos.Command.RVEL,
        arcos.Command.ENABLE,
        arcos.Command.CLOSE,
    ]


def arcos_identity(name: str, type_: str, subtype: str) -> object:
    from robocli.devices.pioneer import RobotIdentity

    return RobotIdentity(name, type_, subtype)


def test_cli_timeout_bounds_the_wait_for_a_silent_robot() -> None:
    """``--timeout`` bounded connecting only; a robot that went silent was waited for 8 s,
    whatever it said."""
    import subprocess
    import sys

    server = ReplayServer(DATA / "a_simpleConnect.jsonl")  # its SIPs, then silence
    proc = subprocess.run(
        [sys.executable, "-m", "robocli", "connect", "pioneer", server.url, "--json",
         "--timeout", "2"],
        capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL,
    )  # fmt: skip
    assert proc.returncode == 3, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert lines == [f"robocli: {server.url}: no SIP for 2 s (robot off, cable unplugged, or "
                     "session closed)"], proc.stderr  # fmt: skip
    assert proc.stdout.count("\n") >= 1  # it was connected, and printed SIPs
