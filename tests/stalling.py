"""What the stall tests share: a transport whose write stalls on an event (before or after
its bytes leave), and a probe of every motion command a simulated Pioneer takes.

A real stall (SIGSTOP, a GC pause, a suspended laptop) lands anywhere; these put it exactly
where a stale set-point could slip through, so each run tests the same thing."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from dataclasses import dataclass

from robocli.protocols.arcos import Command, decode_command
from robocli.sim.pioneer.server import PioneerSim
from robocli.transports import Transport

WAIT = 30.0  #: bounds a failure only; every wait ends on an event
MOTION = frozenset({int(Command.VEL), int(Command.RVEL), int(Command.VEL2)})


def packets(data: bytes) -> Iterator[bytes]:
    """The ARCOS packets (type + arguments) in one write."""
    i = 0
    while i + 3 <= len(data):
        n = data[i + 2]
        yield data[i + 3 : i + 3 + n - 2]  # without the checksum
        i += 3 + n


def moves(data: bytes) -> bool:
    """True when ``data`` holds a motion command with a non-zero argument."""
    for payload in packets(data):
        cmd = decode_command(payload)
        if cmd.command in MOTION and cmd.arg:
            return True
    return False


class StallingTransport(Transport):
    """Wraps a real transport; once :meth:`arm` is called, the next write that would move
    the robot blocks on :attr:`release` (``where``: ``"after"`` its bytes left, or
    ``"before"`` they are handed to the real transport, i.e. between the client's check and
    its write). :attr:`stalled` is set while it blocks. :meth:`close` releases it."""

    def __init__(self, inner: Transport, where: str) -> None:
        super().__init__()
        assert where in ("before", "after")
        self.inner, self.where, self.url = inner, where, inner.url
        self.write_timeout = inner.write_timeout
        self.armed = threading.Event()
        self.stalled = threading.Event()
        self.release = threading.Event()

    def arm(self) -> None:
        self.armed.set()

    def write(
        self, data: bytes, timeout: float | None = None, *, not_after: float | None = None
    ) -> None:
        stall = self.armed.is_set() and moves(bytes(data))
        if stall:
            self.armed.clear()
        if stall and self.where == "before":
            self._stall()
        self.inner.write(data, timeout, not_after=not_after)
        if stall and self.where == "after":
            self._stall()

    def _stall(self) -> None:
        self.stalled.set()
        assert self.release.wait(WAIT), "the stalled write was never released"

    def _read(self, size: int, timeout: float | None) -> bytes:
        return self.inner.read(size, timeout)

    def _wait_readable(self, timeout: float) -> bool:
        return self.inner.wait_readable(timeout)

    def fileno(self) -> int | None:
        return self.inner.fileno()

    def _close(self) -> None:
        self.release.set()
        self.inner.close()


@dataclass(frozen=True)
class Taken:
    """A motion command the simulator took: its code, argument and the robot's watchdog
    trips counted before it."""

    command: int
    arg: object
    trips: int


class MotionProbe:
    """Records every motion command ``sim`` takes (on the simulator's side, under its lock),
    with the watchdog trips counted before it."""

    def __init__(self, sim: PioneerSim) -> None:
        self.taken: list[Taken] = []
        ctl = sim._ctl
        handle = ctl.handle

        def probe(link: object, payload: bytes, now: float) -> bytes | None:
            try:
                cmd = decode_command(payload)
            except Exception:
                cmd = None
            if cmd is not None and cmd.command in MOTION:
                self.taken.append(Taken(int(cmd.command), cmd.arg, ctl.watchdog_trips))
            return handle(link, payload, now)  # type: ignore[arg-type]

        ctl.handle = probe  # type: ignore[method-assign]

    def moving_after_trip(self) -> list[Taken]:
        """Motion commands with a non-zero argument taken after the robot's watchdog
        tripped: a stale set-point resent after the stall."""
        return [t for t in self.taken if t.trips > 0 and t.arg]
