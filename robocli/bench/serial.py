"""What the virtual serial port adds to a round trip: a message written, echoed by the device
on the hub's serial port, read back whole; measured on a local serial line (a pty) alone,
through the hub (:class:`~robocli.devices.hub.serial.VirtualSerial`), and through the hub
behind a local pty (``robocli serial --pty``: what an unmodified toolkit sees). The
yardstick is the iRobot Create's sensor stream, one packet every 15 ms.

POSIX only (pseudo-terminals). Used by ``benchmarks/test_bench_serial.py`` and
:func:`main` (``python -m robocli.bench.serial``).
"""

from __future__ import annotations

import json
import os
import select
import threading
import time
import tty
from collections.abc import Callable
from typing import Any

from robocli.bench.stats import Run, SampleStats

__all__ = ["PATHS", "EchoLine", "round_trips", "serial_latency"]

PATHS = ("pty", "hub", "hub+pty")
"""Where a round trip goes: a local pty only; the hub's port through VirtualSerial; the same
behind a local pty relay."""
TIMEOUT_S = 5.0


class EchoLine:
    """A serial device that echoes every byte: the master of a pty pair (``path``: the line
    a program or the hub opens)."""

    def __init__(self) -> None:
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.path = os.ttyname(self.slave)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._echo, name="echo-line", daemon=True)
        self._thread.start()

    def _echo(self) -> None:
        while not self._stop.is_set():
            if select.select([self.master], [], [], 0.1)[0]:
                try:
                    data = os.read(self.master, 4096)
                except OSError:
                    continue
                while data:
                    data = data[os.write(self.master, data) :]

    def close(self) -> None:
        self._stop.set()
        self._thread.join(1.0)
        os.close(self.master)
        os.close(self.slave)

    def __enter__(self) -> EchoLine:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def round_trips(write: Callable[[bytes], object], read: Callable[[int], bytes], run: Run,
                size: int) -> Run:  # fmt: skip
    """``run.n`` round trips of ``size`` bytes (write, then read them all back)."""
    msg = bytes(range(size % 256)) * (size // 256) + bytes(range(size % 256))
    msg = msg[:size] or b"\0"
    for i in range(run.n):
        t0 = time.perf_counter()
        write(msg)
        got = b""
        while len(got) < len(msg):
            piece = read(len(msg) - len(got))
            if not piece:
                raise TimeoutError(f"{run.name}: the echo did not come back")
            got += piece
        run.samples[i] = time.perf_counter() - t0
        run.count += 1
    return run


def serial_latency(n: int = 500, size: int = 2, baud: int = 115200) -> dict[str, SampleStats]:
    """Round trips of ``size`` bytes on each of :data:`PATHS` (``n`` each), at ``baud``."""
    import serial

    from robocli.devices.hub.relay import PtyRelay
    from robocli.devices.hub.serial import VirtualSerial
    from robocli.hub_server import HubServer

    out: dict[str, SampleStats] = {}
    with EchoLine() as echo:
        with serial.Serial(echo.path, baud, timeout=TIMEOUT_S) as local:
            out["pty"] = SampleStats.of(
                round_trips(local.write, local.read, Run("pty", n), size).values
            )
        with HubServer(port=0, sim=False, serial_ports=[echo.path]) as hub:
            address = f"127.0.0.1:{hub.port}"
            with VirtualSerial.open(address, echo.path, baudrate=baud) as line:
                read = lambda k: line.read(k, TIMEOUT_S)  # noqa: E731
                run = round_trips(line.write, read, Run("hub", n), size)
                out["hub"] = SampleStats.of(run.values)
            with PtyRelay(address, echo.path, baudrate=baud) as relay:
                stop = threading.Event()
                relaying = threading.Thread(target=relay.run, args=(stop,), daemon=True)
                relaying.start()
                try:
                    with serial.Serial(relay.path, baud, timeout=TIMEOUT_S) as program:
                        run = round_trips(program.write, program.read, Run("hub+pty", n), size)
                        out["hub+pty"] = SampleStats.of(run.values)
                finally:
                    stop.set()
                    relaying.join(TIMEOUT_S)
    return out


def main() -> None:  # pragma: no cover - a measurement, printed
    """Print the round trips (ms) of :func:`serial_latency` as JSON, for 2 and 80 bytes
    (a Create command; a group 100 sensor packet)."""
    result: dict[str, Any] = {}
    for size in (2, 80):
        stats = serial_latency(n=500, size=size)
        result[f"{size} B"] = {k: {q: round(v * 1e3, 3) for q, v in s.as_dict().items()
                                   if q in ("median", "p99", "max")}
                               for k, s in stats.items()}  # fmt: skip
    print(json.dumps(result, indent=1))


if __name__ == "__main__":  # pragma: no cover
    main()
