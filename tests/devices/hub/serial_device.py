"""A serial device on the hub's side for the serial stream tests: the master end of a pty pair
whose slave path the hub serves, a thread collecting what reaches it, and a paced duplex
exchange (both directions at once, at a baud rate's byte rate) that checks no byte is lost
or reordered."""

from __future__ import annotations

import os
import random
import select
import termios
import threading
import time
import tty
from collections.abc import Callable, Iterator

import pytest

TIMEOUT = 10.0


class Device:
    """The far end of a serial line: ``path`` is what the hub opens."""

    def __init__(self, echo: bool = False) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self.echo = echo
        self.got = bytearray()
        self._cond = threading.Condition()
        self._stop = threading.Event()
        self._reading = threading.Event()
        self._reading.set()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        while not self._stop.is_set():
            if not self._reading.is_set():  # the line's reader is away: nothing is taken
                self._reading.wait(0.1)
                continue
            if not select.select([self.master], [], [], 0.1)[0]:
                continue
            try:
                data = os.read(self.master, 65536)
            except OSError:  # EIO while nobody holds the slave: keep looking
                continue
            if self.echo:
                self.write(data)
            with self._cond:
                self.got += data
                self._cond.notify_all()

    def pause(self) -> None:
        """Stop taking bytes from the line (a device that does not read)."""
        self._reading.clear()

    def write(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            select.select([], [self.master], [], TIMEOUT)
            view = view[os.write(self.master, view) :]

    def wait_bytes(self, n: int, timeout: float = TIMEOUT) -> bytes:
        """The first ``n`` bytes received (fewer if ``timeout`` passes)."""
        with self._cond:
            self._cond.wait_for(lambda: len(self.got) >= n, timeout)
            return bytes(self.got[:n])

    def settings(self) -> list[object]:
        """The termios settings of the line as the hub set them."""
        return termios.tcgetattr(self.slave)

    def close(self) -> None:
        self._stop.set()
        self._reading.set()
        self._thread.join(2)
        os.close(self.master)
        os.close(self.slave)


@pytest.fixture(name="device")
def device_fixture() -> Iterator[Device]:
    """``device``: a :class:`Device` (import this into a test module to use it)."""
    d = Device()
    yield d
    d.close()


def paced(write: Callable[[bytes], object], data: bytes, rate: float, stop: threading.Event,
          chunk: int = 64) -> None:  # fmt: skip
    """Write ``data`` in pieces of ``chunk`` at ``rate`` bytes/s (the line's speed)."""
    start = time.monotonic()
    for i in range(0, len(data), chunk):
        due = start + i / rate
        if stop.wait(max(0.0, due - time.monotonic())):
            return
        write(data[i : i + chunk])


def duplex(
    to_device: Callable[[bytes], object],
    from_device: Callable[[int, float], bytes],
    device: Device,
    seconds: float,
    baud: int = 115200,
) -> tuple[bytes, bytes, bytes, bytes]:
    """Both directions at once for ``seconds`` at ``baud`` (10 bits a byte): (sent to the
    device, what it got, sent by the device, what came back). ``from_device(n, timeout)``
    returns the first ``n`` bytes the client received."""
    rate = baud / 10
    n = int(seconds * rate)
    up, down = random.Random(1).randbytes(n), random.Random(2).randbytes(n)
    stop = threading.Event()
    writers = [
        threading.Thread(target=paced, args=(to_device, up, rate, stop), daemon=True),
        threading.Thread(target=paced, args=(device.write, down, rate, stop), daemon=True),
    ]
    for w in writers:
        w.start()
    try:
        got_down = from_device(n, seconds + TIMEOUT)
        got_up = device.wait_bytes(n, TIMEOUT)
    finally:
        stop.set()
        for w in writers:
            w.join(TIMEOUT)
    return up, got_up, down, got_down
