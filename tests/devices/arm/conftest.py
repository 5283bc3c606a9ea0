"""Fixtures of the arm tests: ABB simulators on ephemeral ports, a raw Simple Message client
(an independent struct-based framer, not the code under test) and the recorded traces."""

from __future__ import annotations

import json
import socket
import struct
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from robocli.devices.arm import Arm
from robocli.sim.abb.server import AbbSim
from tests import paths

DATA = paths.DATA / "simple_message"
VARIANTS = {"le": ("<", 4), "bswap": (">", 4), "float64": ("<", 8)}


def vectors(variant: str) -> dict[str, dict[str, Any]]:
    items = json.loads((DATA / f"vectors_{variant}.json").read_text())
    return {v["name"]: v for v in items}


def exchange(variant: str) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (DATA / f"exchange_{variant}.jsonl").read_text()
            .splitlines() if line.strip()]  # fmt: skip


def port_of(url: str) -> int:
    return int(url.rsplit(":", 1)[1])


class RawSM:
    """A bare Simple Message client: whole frames by byte counting, nothing else."""

    def __init__(self, port: int, order: str = "<") -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=5.0)
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.order = order
        self.buf = b""

    def send(self, data: bytes) -> None:
        self.sock.sendall(data)

    def frame(self, timeout: float = 5.0) -> bytes | None:
        """The next whole frame, or None after ``timeout`` (or when the peer closed)."""
        deadline = time.monotonic() + timeout
        while True:
            if len(self.buf) >= 4:
                (n,) = struct.unpack(self.order + "i", self.buf[:4])
                if len(self.buf) >= 4 + n:
                    out, self.buf = self.buf[: 4 + n], self.buf[4 + n :]
                    return out
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            self.sock.settimeout(left)
            try:
                data = self.sock.recv(65536)
            except (TimeoutError, OSError):
                return None
            if not data:
                return None
            self.buf += data

    def closed_by_peer(self, timeout: float = 5.0) -> bool:
        self.sock.settimeout(timeout)
        try:
            while True:
                if not self.sock.recv(65536):
                    return True
        except (TimeoutError, OSError) as exc:
            return not isinstance(exc, TimeoutError)

    def close(self) -> None:
        self.sock.close()


@pytest.fixture
def make_sim() -> Iterator[Callable[..., tuple[AbbSim, int, int]]]:
    """Start simulators (ephemeral ports, faster than real time by default)."""
    sims: list[AbbSim] = []

    def make(**kw: Any) -> tuple[AbbSim, int, int]:
        kw.setdefault("time_scale", 4.0)
        kw.setdefault("state_ms", 10.0)
        sim = AbbSim(**kw)
        sims.append(sim)
        motion, state = sim.serve_tcp("127.0.0.1", 0, 0)
        return sim, port_of(motion), port_of(state)

    yield make
    for sim in sims:
        sim.close()


@pytest.fixture
def make_arm() -> Iterator[Callable[..., Arm]]:
    arms: list[Arm] = []

    def make(motion_port: int, state_port: int, **kw: Any) -> Arm:
        arm = Arm.connect("127.0.0.1", motion_port, state_port, **kw)
        arms.append(arm)
        return arm

    yield make
    for arm in arms:
        arm.close()


class TalkingServer:
    """A TCP server that sends ``payload`` to each client, repeatedly (another protocol, or
    canned Simple Message frames)."""

    def __init__(self, payload: bytes, repeat: float = 0.05) -> None:
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.port = self.sock.getsockname()[1]
        self.payload, self.repeat = payload, repeat
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        self.sock.settimeout(0.1)
        conns = []
        while not self.stop.is_set():
            try:
                conn, _ = self.sock.accept()
                conns.append(conn)
            except (TimeoutError, OSError):
                pass
            for c in list(conns):
                try:
                    c.sendall(self.payload)
                except OSError:
                    conns.remove(c)
            self.stop.wait(self.repeat)
        for c in conns:
            c.close()

    def close(self) -> None:
        self.stop.set()
        self.thread.join(2)
        self.sock.close()


@pytest.fixture
def sim_arm(
    make_sim: Callable[..., tuple[AbbSim, int, int]], make_arm: Callable[..., Arm]
) -> tuple[AbbSim, Arm]:
    """A simulator (``make_sim``'s defaults) and an arm connected to it that has its first
    state."""
    sim, mp, sp = make_sim()
    arm = make_arm(mp, sp)
    arm.wait_for_state()
    return sim, arm


@pytest.fixture
def talking_server() -> Iterator[Callable[[bytes], TalkingServer]]:
    servers: list[TalkingServer] = []

    def make(payload: bytes) -> TalkingServer:
        s = TalkingServer(payload)
        servers.append(s)
        return s

    yield make
    for s in servers:
        s.close()
