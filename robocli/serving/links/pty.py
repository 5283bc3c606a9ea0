"""A link over the master side of a pseudo-terminal (:class:`PtyLink`), a serial line.

Part of :mod:`robocli.serving.links` (import from there).
"""

from __future__ import annotations

import errno
import logging
import os
import select
import time
from collections.abc import Callable

from robocli.errors import TransportError
from robocli.serving.links.base import RECV_SIZE, Link
from robocli.serving.links.limits import LinkLimits

log = logging.getLogger("robocli.serving.server")


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
        os.set_blocking(self._wake_w, False)  # a wake-up never waits: one byte is enough
        #: the end of a message the line could not take whole (tx lock held to touch it)
        self._rest: bytes | None = None

    def _write_now(self, data: bytes | bytearray | memoryview) -> int:
        """A message goes out whole or not at all, as on a serial line: one the line cannot
        take at all now is dropped whole (counted), as with nobody listening; of one it takes
        in part, the rest goes out first as the line drains (the link thread waits for room),
        and messages coming meanwhile are dropped whole. The queue is always emptied."""
        if self._rest is not None and not self._write_rest():
            self._drop(len(data))
            return len(data)
        with memoryview(data) as view:
            sent = self._write_some(view)
            if 0 < sent < len(view):
                self._rest = bytes(view[sent:])  # at most one message
                self._nudge()  # the link thread now waits for room
            elif sent == 0 and len(view):
                self._drop(len(view))
        return len(data)

    def _write_some(self, view: memoryview) -> int:
        sent = 0
        try:
            while sent < len(view):
                sent += os.write(self.master, view[sent:])
        except BlockingIOError:
            pass
        self._stats.bytes_out += sent
        return sent

    def _write_rest(self) -> bool:
        """Write what waits of a message cut by a full line; whether all of it went."""
        rest = self._rest
        if rest is None:
            return True
        with memoryview(rest) as view:
            sent = self._write_some(view)
        self._rest = rest[sent:] if sent < len(rest) else None
        return self._rest is None

    def _drop(self, n: int) -> None:
        self._stats.tx_dropped += n
        log.debug("%s: line full: dropped a message of %d bytes", self.name, n)

    def _nudge(self) -> None:
        try:
            os.write(self._wake_w, b"x")
        except OSError:
            pass  # already released, or woken already (the pipe is full)

    def _interrupt(self) -> None:
        self._nudge()

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
            room = [master] if self._rest is not None else []
            ready, writable, _ = select.select([master, wake], room, [], timeout)
            now = time.monotonic()
            if writable:
                with self._tx_lock:
                    self._write_rest()
            if not ready:
                if deadline is not None and now >= deadline:
                    self.send(self._abandon_partial(now))
                continue
            if wake in ready:  # closing, or a cut message to finish: look again
                os.read(wake, 64)
                continue
            try:
                data = os.read(master, RECV_SIZE)
            except BlockingIOError:
                continue
            except OSError as exc:  # EIO: no process holds the slave end right now
                if exc.errno != errno.EIO:
                    raise TransportError(f"{self.name}: read failed: {exc}") from exc
                if select.select([wake], [], [], 0.05)[0]:
                    os.read(wake, 64)  # closing (the loop ends), or a cut message waits
                continue
            if data:
                self.send(self._feed(data, now))

    def _release(self) -> None:
        for fd in (self.master, self.slave, self._wake_r, self._wake_w):
            os.close(fd)
