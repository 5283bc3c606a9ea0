"""SCIP 2.0 framing in pure Python, both ways: :class:`RequestFramer` splits what a client
sends into request lines (the simulator's, and a recording's client side), and
:class:`ReplyFramer` finds whole reply blocks in
any chunking of a byte stream, resynchronising line by line after garbage and counting what
it dropped. It is the reference of the C framer (``Framer("scip2")`` of :mod:`robocli.core`,
wrapped by :mod:`robocli.protocols.scip2.fast`): the two return the same blocks and the
same counters for the same stream.

The rules (both implementations):

* A block starts with an echo line (1..64 printable chars; a longer line cannot be an echo),
  followed by a status line: 3 chars whose third is the sum of the first two, or 1 char (the
  SCIP 1.1 status, the ``SCIP2.0`` switch's bare ``0``). It runs to the first empty line.
* Lines end in LF; a CR just before an LF is tolerated (a CR anywhere else is garbage).
* Outside a block, an empty line is dropped (1 byte). A byte that is not printable ASCII ends
  the candidate: everything up to and including it is dropped. A candidate whose status line
  is wrong, or whose body holds a garbage byte, a line over 128 chars, or runs past
  ``max_block`` bytes, loses its first line (dropped) and the next line is tried as an echo.
* Counters: ``frames``; ``dropped_bytes``; ``bad_checksums`` (status lines of 3 chars whose
  sum is wrong); ``bad_lengths`` (candidates dropped for garbage bytes, over-long lines or
  blocks).

Requests (:class:`RequestFramer`, the same interface as :class:`robocli.core.Framer`): a
request ends in LF, CR or CR LF (one terminator); empty lines are skipped; a line longer than
:data:`MAX_REQUEST` bytes without a terminator is dropped whole (counted), so a stream of
garbage never grows the buffer.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from robocli.core import FramerStats
from robocli.protocols.common import PartialFrame
from robocli.protocols.scip2.wire import MAX_BLOCK, MAX_ECHO, MAX_LINE, checksum


@dataclass(frozen=True)
class ReplyFramerStats:
    """Counters of a framer since creation (the same fields as ``robocli.core.FramerStats``)."""

    frames: int
    dropped_bytes: int
    bad_checksums: int
    bad_lengths: int


_EVENT = re.compile(rb"[^\x20-\x7e]")  # an LF, a CR, or garbage: where a line scan stops


class _Wait(Exception):
    """More bytes are needed to judge the candidate."""


class ReplyFramer(PartialFrame):
    """Pure-Python SCIP 2.0 reply framer (see the module's rules). Not thread-safe."""

    def __init__(self, max_block: int = MAX_BLOCK) -> None:
        if max_block < 8:
            raise ValueError("max_block must be at least 8 bytes")
        super().__init__()
        self.max_block = max_block
        self._frames = self._dropped = self._bad_sums = self._bad_lengths = 0

    @property
    def stats(self) -> ReplyFramerStats:
        return ReplyFramerStats(self._frames, self._dropped, self._bad_sums, self._bad_lengths)

    def feed(self, data: bytes | bytearray | memoryview) -> list[bytes]:
        """Append ``data`` and return every block now complete, in order."""
        self._buf += data
        out: list[bytes] = []
        while True:
            block = self._next()
            if block is None:
                return out
            out.append(block)

    def _drop(self, n: int) -> None:
        del self._buf[:n]
        self._dropped += n

    def _line(self, at: int, limit: int) -> tuple[int, int]:
        """(content end, next line start) of the line at ``at``: raises _Wait when its LF has
        not arrived within ``limit`` chars; returns content end -2 - k for a garbage byte at
        k (k >= at), and -1 for a line longer than ``limit``. Scanning stops at the first LF
        or non-printable byte (found by a regex), as the C framer's byte loop does."""
        buf = self._buf
        n = len(buf)
        over = at + limit + 1  # a printable char here makes the line too long
        m = _EVENT.search(buf, at, over + 1)
        pos = m.start() if m is not None else n
        if pos > over:
            return -1, over
        if pos >= n:
            if n >= over:
                return -1, over
            raise _Wait
        c = buf[pos]
        if c == 0x0A:
            return (-1, pos + 1) if pos - at > limit else (pos, pos + 1)
        if c == 0x0D:
            if pos + 1 >= n:
                raise _Wait
            if buf[pos + 1] == 0x0A:
                return (-1, pos) if pos - at > limit else (pos, pos + 2)
        return -2 - pos, pos + 1

    def _next(self) -> bytes | None:
        buf = self._buf
        while buf:
            if buf[0] == 0x0A:
                self._drop(1)
                continue
            try:
                end, nxt = self._line(0, MAX_ECHO)
                if end < -1:  # garbage byte at -2 - end: drop through it
                    self._bad_lengths += 1
                    self._drop(-1 - end)
                    continue
                if end <= 0:  # too long for an echo (or a bare CR LF): drop what was scanned
                    self._drop(nxt)
                    continue
                send, snxt = self._line(nxt, 4)
                slen = send - nxt
                if send >= nxt and slen == 3 and buf[nxt + 2] != checksum(buf[nxt : nxt + 2]):
                    self._bad_sums += 1
                    self._drop(nxt)
                    continue
                if send < nxt or slen not in (1, 3):
                    self._drop(nxt)
                    continue
                at = snxt
                while True:
                    if at > self.max_block:
                        break
                    lend, lnxt = self._line(at, MAX_LINE)
                    if lend < at:
                        break
                    if lend == at:  # the empty line: the block is complete
                        if lnxt > self.max_block:
                            break
                        block = bytes(buf[:lnxt])
                        del buf[:lnxt]
                        self._frames += 1
                        return block
                    at = lnxt
                self._bad_lengths += 1
                self._drop(nxt)
            except _Wait:
                if len(buf) > self.max_block:
                    self._bad_lengths += 1
                    self._drop(self._first_line_len())
                    continue
                return None
        return None

    def _first_line_len(self) -> int:
        at = self._buf.find(b"\n")
        return at + 1 if at >= 0 else len(self._buf)


#: Longest request line taken (bytes, terminator excluded): ``MD`` + 13 digits + ``;`` +
#: 16 string characters is 32; a sensor's buffer is not much larger.
MAX_REQUEST = 64


class RequestFramer(PartialFrame):
    """Splits a byte stream into request lines (without their terminator)."""

    def __init__(self, max_line: int = MAX_REQUEST) -> None:
        super().__init__()
        self.max_line = max_line
        self._after_cr = False  # the last terminator was a CR: a LF next belongs to it
        self._skipping = False  # inside an over-long line: drop up to its terminator
        self._frames = 0
        self._dropped = 0
        self._oversize = 0

    def feed(self, data: bytes) -> list[bytes]:
        """Append ``data``; every request line now complete, in order."""
        out: list[bytes] = []
        buf = self._buf
        for b in data:
            if b in (10, 13):
                if b == 10 and self._after_cr:
                    self._after_cr = False
                    continue
                self._after_cr = b == 13
                if self._skipping:
                    self._skipping = False
                elif buf:
                    out.append(bytes(buf))
                    self._frames += 1
                buf.clear()
                continue
            self._after_cr = False
            if self._skipping:
                self._dropped += 1
                continue
            buf.append(b)
            if len(buf) > self.max_line:
                self._dropped += len(buf)
                self._oversize += 1
                self._skipping = True
                buf.clear()
        return out

    def reset(self) -> None:
        """Forget the partial line (the counters are kept)."""
        super().reset()
        self._after_cr = self._skipping = False

    @property
    def stats(self) -> FramerStats:
        return FramerStats(self._frames, self._dropped, 0, self._oversize)
