"""A motion link lost after the last point (-3) went out but before its acknowledgement: the
controller may have activated the trajectory, so the arm may be moving. The client says so,
reconnects once and sends STOP (-4). Tested against the built-in ABB simulator through a
proxy that cuts the link at that moment."""

from __future__ import annotations

import contextlib
import socket
import struct
import threading
from collections.abc import Callable, Iterator

import pytest

from robocli.devices.arm import Arm
from robocli.errors import ConnectionLost
from robocli.kinematics import load_model
from robocli.kinematics.trajectory import circle

IRB = load_model("irb120")
WAIT = 30.0  #: bounds a failure only
END, STOP = -3, -4


class CutAfterActivation:
    """A TCP proxy in front of a motion port. On the first connection, once a point with
    sequence -3 went through and the controller acknowledged it, it keeps the
    acknowledgement, closes the controller's side, calls ``cut`` (which waits until the
    controller saw it go), then resets the client's side. Later connections pass through.
    It records the sequence numbers each connection carried."""

    def __init__(self, port: int, cut: Callable[[], None]) -> None:
        self.target = ("127.0.0.1", port)
        self.cut = cut
        self.sequences: list[list[int]] = []
        self.srv = socket.create_server(("127.0.0.1", 0))
        self.port = self.srv.getsockname()[1]
        self.socks: list[socket.socket] = []
        self.relaying = threading.Event()  #: set once the first connection is relayed
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        try:
            while True:
                client, _ = self.srv.accept()
                robot = socket.create_connection(self.target, timeout=WAIT)
                self.socks += [client, robot]
                self.relaying.set()
                seqs: list[int] = []
                self.sequences.append(seqs)
                first = len(self.sequences) == 1
                if not first:  # the first one relays each reply itself (it keeps one back)
                    threading.Thread(target=self._pump, args=(robot, client),
                                     daemon=True).start()  # fmt: skip
                threading.Thread(target=self._requests, args=(client, robot, seqs, first),
                                 daemon=True).start()  # fmt: skip
        except OSError:
            return

    @staticmethod
    def _frames(sock: socket.socket) -> Callable[[], bytes | None]:
        buf = b""

        def next_frame() -> bytes | None:
            nonlocal buf
            while True:
                if len(buf) >= 4:
                    (n,) = struct.unpack("<i", buf[:4])
                    if len(buf) >= 4 + n:
                        out, buf = buf[: 4 + n], buf[4 + n :]
                        return out
                data = sock.recv(65536)
                if not data:
                    return None
                buf += data

        return next_frame

    def _requests(self, client: socket.socket, robot: socket.socket, seqs: list[int],
                  first: bool) -> None:  # fmt: skip
        try:
            next_frame, next_reply = self._frames(client), self._frames(robot)
            while (frame := next_frame()) is not None:
                (seq,) = struct.unpack_from("<i", frame, 16)  # JOINT_TRAJ_PT's sequence
                seqs.append(seq)
                robot.sendall(frame)
                if not first:
                    continue
                reply = next_reply()  # a controller's motion port only ever answers
                assert reply is not None
                if seq == END:
                    self._cut(client, robot)  # the acknowledgement is kept
                    return
                client.sendall(reply)
        except OSError:
            pass

    def _cut(self, client: socket.socket, robot: socket.socket) -> None:
        robot.close()
        self.cut()
        client.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        client.close()  # a reset: the link is lost

    @staticmethod
    def _pump(src: socket.socket, dst: socket.socket) -> None:
        try:
            while data := src.recv(65536):
                dst.sendall(data)
        except OSError:
            pass

    def close(self) -> None:
        self.srv.close()
        for s in self.socks:
            s.close()


@contextlib.contextmanager
def _cut_download(proxy: CutAfterActivation, sp: int) -> Iterator[tuple[Arm, str]]:
    """An arm connected through ``proxy`` whose download of a long circle ended in
    ConnectionLost: the arm and the error's message (arm and proxy closed afterwards)."""
    arm = Arm.connect("127.0.0.1", proxy.port, sp, timeout=WAIT)
    try:
        arm.wait_for_state()
        with pytest.raises(ConnectionLost) as info:
            arm.download(circle(IRB, 20, duration=60.0))
        yield arm, str(info.value)
    finally:
        arm.close()
        proxy.close()


def test_link_lost_before_the_activation_is_acknowledged(make_sim) -> None:
    sim, mp, sp = make_sim(time_scale=2.0)
    proxy = CutAfterActivation(mp, lambda: sim.wait_until(lambda s: s.motion_clients == 0, WAIT))
    with _cut_download(proxy, sp) as (arm, message):
        assert "after the last point (-3) went out, before its acknowledgement" in message
        assert "the arm may be moving" in message
        assert "STOP (-4) sent over a new connection, and acknowledged" in message
        assert message.count("tcp://") == 1
        s = sim.wait_until(lambda s: s.stops == 1, WAIT)
        assert s.trajectories == 1 and s.motion_accepted == 2  # activated; STOP on a new link
        assert proxy.sequences[0][0] == -1 and proxy.sequences[0][-1] == END
        assert proxy.sequences[1] == [STOP]
        sim.wait_until(lambda s: not s.in_motion, WAIT)  # stopped, long before its 60 s
        assert not arm.running()


def test_no_stop_when_nothing_was_activated(make_sim) -> None:
    """A link lost before -3 went out is a plain "link lost": nothing can be moving."""
    sim, mp, sp = make_sim(time_scale=2.0)
    proxy = CutAfterActivation(mp, lambda: None)
    arm = Arm.connect("127.0.0.1", proxy.port, sp, timeout=WAIT)
    try:
        arm.wait_for_state()
        assert proxy.relaying.wait(WAIT)
        proxy.close()  # both sides of the motion link go
        with pytest.raises(ConnectionLost) as info:
            arm.download(circle(IRB, 20, duration=60.0))
        assert "may be moving" not in str(info.value)
        assert sim.snapshot().stops == 0 and sim.snapshot().trajectories == 0
    finally:
        arm.close()


def test_the_error_says_when_the_stop_could_not_be_sent(make_sim) -> None:
    """The controller cannot be reached again: the arm may be moving, and nothing stopped it."""
    sim, mp, sp = make_sim(time_scale=2.0)
    proxy: CutAfterActivation | None = None

    def unreachable() -> None:
        assert proxy is not None
        proxy.srv.shutdown(socket.SHUT_RDWR)  # no new connection gets through
        proxy.srv.close()

    proxy = CutAfterActivation(mp, unreachable)
    with _cut_download(proxy, sp) as (arm, message):
        assert message.count("tcp://") == 1 and (
            "the arm may be moving, and STOP (-4) could not be sent over a new connection "
            "(connection refused)" in message
        )
        assert message.endswith("stop it at the controller"), message
        assert sim.snapshot().stops == 0 and sim.snapshot().in_motion
