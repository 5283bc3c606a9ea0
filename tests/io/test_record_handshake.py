"""A recorder attaches before a link's first byte: the raw channels of a recording start with
the handshake, byte for byte as it went over the wire (issue 21, point 10)."""

from __future__ import annotations

import contextlib
import socket
import threading
from collections.abc import Iterator
from pathlib import Path

from mcap.reader import make_reader

from robocli.hub_server import HubServer
from robocli.io.record.reader import raw_frame
from robocli.protocols import ros4mat
from robocli.sim.abb.server import AbbSim
from tests.commands.helpers import run


class _Tap:
    """A TCP relay on an ephemeral loopback port to ``upstream`` for one client, keeping
    every byte each way (``c2s``, ``s2c``)."""

    def __init__(self, upstream: tuple[str, int]) -> None:
        self.upstream = upstream
        self.c2s, self.s2c = bytearray(), bytearray()
        self._server = socket.create_server(("127.0.0.1", 0))
        self.port = self._server.getsockname()[1]
        self._threads: list[threading.Thread] = []
        self._done = threading.Event()
        accept = threading.Thread(target=self._accept, daemon=True)
        accept.start()
        self._threads.append(accept)

    def _accept(self) -> None:
        self._server.settimeout(30)
        try:
            client, _ = self._server.accept()
        except OSError:
            return
        server = socket.create_connection(self.upstream, timeout=10)
        for src, dst, into in ((client, server, self.c2s), (server, client, self.s2c)):
            t = threading.Thread(target=self._pump, args=(src, dst, into), daemon=True)
            t.start()
            self._threads.append(t)

    def _pump(self, src: socket.socket, dst: socket.socket, into: bytearray) -> None:
        src.settimeout(60)
        try:
            while data := src.recv(65536):
                into += data
                dst.sendall(data)
        except OSError:
            pass
        finally:
            for s in (src, dst):
                with contextlib.suppress(OSError):
                    s.shutdown(socket.SHUT_RDWR)

    def close(self) -> None:
        self._server.close()
        for t in self._threads:
            t.join(30)


@contextlib.contextmanager
def _tapped(upstream: tuple[str, int]) -> Iterator[_Tap]:
    tap = _Tap(upstream)
    try:
        yield tap
    finally:
        tap.close()


def _raw(path: Path, topic: str) -> list[bytes]:
    """The raw channel's messages in the order written."""
    with path.open("rb") as f:
        items = make_reader(f).iter_messages(topics=[topic], log_time_order=False)
        return [raw_frame(c.message_encoding, bytes(m.data)) for _, c, m in items]


def _starts_the_stream(frames: list[bytes], wire: bytes) -> None:
    got = b"".join(frames)
    assert frames and got == bytes(wire[: len(got)])  # from byte 0, nothing missed


def test_a_hub_recording_starts_with_connect_and_its_ack(tmp_path: Path) -> None:
    path = tmp_path / "hub.mcap"
    with HubServer(port=0, sim=True) as hub, _tapped(("127.0.0.1", hub.port)) as tap:
        proc = run("record", "--hub", f"127.0.0.1:{tap.port}", "-n", "40", "-o", str(path))
        assert proc.returncode == 0, proc.stderr
    tx, rx = _raw(path, "/hub/raw/tx"), _raw(path, "/hub/raw/rx")
    _starts_the_stream(tx, tap.c2s)
    _starts_the_stream(rx, tap.s2c)
    assert tx[0][0] == ros4mat.MsgType.CONNECT and rx[0][0] == ros4mat.MsgType.CONNECT_ACK


def test_an_arm_recording_starts_with_the_first_state_frame(tmp_path: Path) -> None:
    path = tmp_path / "arm.mcap"
    with AbbSim("irb120", state_ms=5.0, feedback=True) as sim:
        _, state = sim.serve_tcp("127.0.0.1", 0, 0)
        port = int(state.rsplit(":", 1)[1])
        with _tapped(("127.0.0.1", port)) as tap:
            proc = run("record", "--arm", "127.0.0.1", "--state-port", str(tap.port), "-n", "60",
                       "-o", str(path))  # fmt: skip
            assert proc.returncode == 0, proc.stderr
    _starts_the_stream(_raw(path, "/arm/raw/state/rx"), tap.s2c)
