"""The serving layer's pty link when its line is full: messages go out whole or not at all.

A simulator pushing a stream (a Create's 15 ms frames, a Pioneer's SIPs) into a pty that
nobody reads fills the line; the message the line took in part must be finished as the
reader drains it, and the messages that found the line full dropped whole, so that what the
reader gets is a run of whole messages, never a cut one followed by the next.
"""

from __future__ import annotations

import os
import select
import time

import pytest

from robocli.protocols import arcos
from robocli.serving.server import Server
from tests.waiting import wait_for

pytestmark = pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pty")
WAIT = 10.0


class Quiet:
    """A session that answers nothing."""

    def on_frame(self, frame: bytes, now: float) -> bytes | None:
        return None

    def on_close(self) -> None:
        pass


def test_a_full_pty_cuts_no_message() -> None:
    import termios
    import tty

    message = arcos.frame(bytes(range(200)))  # 205 bytes: never a divisor of a pty buffer
    server = Server(lambda link: Quiet(), protocol="arcos", name="ptyfull")
    try:
        path = server.serve_pty()
        (link,) = server.links()
        pushed = 0
        end = time.monotonic() + WAIT
        while link.stats.tx_dropped < 3 * len(message):  # the line is full for a while
            assert time.monotonic() < end, "the line never filled"
            link.send(message)
            pushed += 1
        dropped = link.stats.tx_dropped
        assert dropped % len(message) == 0, f"{dropped} bytes dropped: a message was cut"
        whole = pushed - dropped // len(message)
        fd = os.open(path, os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK)
        try:
            tty.setraw(fd, termios.TCSANOW)
            got = bytearray()
            end = time.monotonic() + WAIT
            while len(got) < whole * len(message):
                left = end - time.monotonic()
                assert left > 0, f"{len(got)} of {whole * len(message)} bytes came"
                if select.select([fd], [], [], left)[0]:
                    got += os.read(fd, 65536)
        finally:
            os.close(fd)
        assert bytes(got) == message * whole  # whole messages, in order, none cut
        # the link counts a write after it returns: the reader may have the bytes first
        wait_for(lambda: link.stats.bytes_out == len(got), "every byte read counted as sent")
    finally:
        server.close()
