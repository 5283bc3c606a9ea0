"""A link over the master side of a pseudo-terminal (:class:`PtyLink`), a serial line.

Part of :mod:`robocli.sim.links` (import from there).
"""

from __future__ import annotations

import errno
import logging
import os
import select
import time
from collections.abc import Callable

from robocli.errors import TransportError
from robocli.sim.links.base import RECV_SIZE, Link
from robocli.sim.links.limits import LinkLimits

log = logging.getLogger("robocli.sim.serving")


class PtyLink(Link):
    """The master side of a pseudo-terminal in raw mode (a serial line)."""

    def __init__(
        self, limits: LinkLimits, master: int, slave: int, path: str,
        on_end: Callable[[Link], None],
    ) -> None:  # fmt: skip
        super().__init__(limits, f"pty {path}", on_end)
        self.established = True  # one line, no handshake to wait for
        self.master, self.slave = master, slave
        self._wake_r, self._wake_w = os.pipe()

    def _write_now(self, data: bytes | bytearray | memoryview) -> int:
        """What the pty cannot take now is dropped, as on a serial line with nobody
        listening: the queue is always emptied."""
        view = memoryview(data)
        sent = 0
        try:
            while sent < len(view):
                sent += os.write(self.master, view[sent:])
        except BlockingIOError:
            self._stats.tx_dropped += len(view) - sent
            log.debug("%s: line full: dropped %d bytes", self.name, len(view) - sent)
        finally:
            view.release()
        self._stats.bytes_out += sent
        return len(data)

    def _interrupt(self) -> None:
        try:
            os.write(self._wake_w, b"x")
        except OSError:
            pass  # already released

    def _serve(self) -> None:
        master, wake = self.master, self._wake_r
        while not self._closed:
            if self._held or self._unframed is not None:
                self.send(self._resume(time.monotonic()))
                continue
            if self._ending:
                return
            deadline = self._partial_deadline()
            timeout = None if deadline is None else max(0.0, deadline - time.monotonic())
            ready, _, _ = select.select([master, wake], [], [], timeout)
            now = time.monotonic()
            if not ready:
                if deadline is not None and now >= deadline:
                    self.send(self._abandon_partial(now))
                continue
            if wake in ready:
                return
            try:
                data = os.read(master, RECV_SIZE)
            except BlockingIOError:
                continue
            except OSError as exc:  # EIO: no process holds the slave end right now
                if exc.errno != errno.EIO:
                    raise TransportError(f"{self.name}: read failed: {exc}") from exc
                if select.select([wake], [], [], 0.05)[0]:
                    return
                continue
            if data:
                self.send(self._feed(data, now))

    def _release(self) -> None:
        for fd in (self.master, self.slave, self._wake_r, self._wake_w):
            os.close(fd)
