"""What one session of the simulated scanner sends, a whole frame at a time
(:class:`FrameOutput`).

A sensor never sends part of a frame: when its host reads too slowly it drops whole scans
and counts them (docs/protocols/scip2.md section 5). Over TCP the link queues whatever the
kernel does not take, whole; a scan is dropped while more than :data:`TCP_BEHIND` bytes wait for the
client (a client that reads nothing for the serving layer's send timeout is dropped there).
On a pty the link drops what the line cannot take now (counted in
:attr:`~robocli.serving.server.ServerLinkStats.tx_dropped`), which would cut a frame: here the
part of a frame the line did not take is kept and sent first at the next chance (every scan tick),
replies wait behind it in order (at most :data:`MAX_WAITING` bytes), and scans due meanwhile
are dropped whole. A scan is dropped too while the client's side already holds a full read
buffer (nobody reads the line), so that what it finds there is never long stale.
"""

from __future__ import annotations

import fcntl
import logging
import struct
import termios
import threading
from collections import deque
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from robocli.serving.server import Link

__all__ = ["MAX_WAITING", "PTY_READ_BUFFER", "TCP_BEHIND", "FrameOutput"]

log = logging.getLogger("robocli.sim.hokuyo")

PTY_READ_BUFFER = 4095  #: Linux n_tty's read buffer: FIONREAD on the slave stops there
MAX_WAITING = 64 << 10  #: bytes of replies that may wait behind a frame the line took in part
TCP_BEHIND = 64 << 10  #: scans are dropped while this much output waits for a TCP client


class FrameOutput:
    """The output of one session to its link: replies and scan frames, each whole or not at
    all. Thread-safe (the link's thread sends replies, the scan clock's thread frames)."""

    def __init__(self, link: Link) -> None:
        self.link = link
        self.slave: int | None = getattr(link, "slave", None)  #: a pty's client side
        self._lock = threading.Lock()
        self._rest = b""  # the part of a frame the line has not taken yet
        self._waiting: deque[bytes] = deque()  # replies behind it, in order
        self._waiting_bytes = 0
        self.scans_dropped = 0  #: scans not sent: the client read too slowly (or the clock lagged)
        self.replies_dropped = 0  #: replies not sent: more than MAX_WAITING waited

    def scan(self, frame: bytes) -> bool:
        """Send a scan's frame whole, or drop it (counted) when the client is behind;
        whether it went out."""
        with self._lock:
            if self.slave is None:
                if self.link.pending_output > TCP_BEHIND:
                    self.scans_dropped += 1
                    return False
                return self.link.send(frame)
            self._flush()
            if self._rest or self._waiting or self._line_full():
                self.scans_dropped += 1
                return False
            self._write(frame)
            return True

    def dropped(self, scans: int) -> None:
        """Count ``scans`` not sent for another reason (a scan clock that fell behind)."""
        with self._lock:
            self.scans_dropped += scans

    def reply(self, data: bytes) -> None:
        """Send a reply whole, after what waits already."""
        with self._lock:
            if self.slave is None:
                self.link.send(data)
                return
            self._flush()
            if not (self._rest or self._waiting):
                self._write(data)
            elif self._waiting_bytes + len(data) <= MAX_WAITING:
                self._waiting.append(data)
                self._waiting_bytes += len(data)
            else:
                self.replies_dropped += 1
                log.debug("%s: %d bytes of replies wait; one dropped", self.link.name,
                          self._waiting_bytes)  # fmt: skip

    def flush(self) -> None:
        """Send what waits, as far as the line takes it (each scan tick calls it)."""
        with self._lock:
            self._flush()

    @property
    def behind(self) -> bool:
        """Whether part of a frame, or a reply, waits for the line."""
        with self._lock:
            return bool(self._rest or self._waiting)

    # ---------------------------------------------------------------- lock held

    def _flush(self) -> None:
        if self._rest:
            self._rest = self._rest[self._write_some(self._rest) :]
        while not self._rest and self._waiting:
            data = self._waiting.popleft()
            self._waiting_bytes -= len(data)
            self._write(data)

    def _write(self, data: bytes) -> None:
        n = self._write_some(data)
        if n < len(data):
            self._rest = data[n:]

    def _write_some(self, data: bytes) -> int:
        """Bytes of ``data`` the pty took: the link drops the rest and counts it."""
        before = self.link.stats.tx_dropped
        if not self.link.send(data):
            return len(data)  # the link is gone: nothing more will go out
        return len(data) - max(0, self.link.stats.tx_dropped - before)

    def _line_full(self) -> bool:
        """Whether the client's side of the pty holds a full read buffer already (nobody
        reads the line)."""
        try:
            raw = fcntl.ioctl(self.slave, termios.FIONREAD, b"\0\0\0\0")  # type: ignore[arg-type]
        except OSError:
            return False
        return bool(struct.unpack("i", raw)[0] >= PTY_READ_BUFFER)
