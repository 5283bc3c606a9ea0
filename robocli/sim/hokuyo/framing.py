"""Request lines of a SCIP sensor, framed for the serving layer (:class:`RequestFramer`).

A request ends in LF, CR or CR LF (one terminator); empty lines are skipped; a line longer
than :data:`MAX_REQUEST` bytes without a terminator is dropped whole (counted), so a stream of
garbage never grows the buffer. Same interface as :class:`robocli.core.Framer`.
"""

from __future__ import annotations

from robocli.core import FramerStats

__all__ = ["MAX_REQUEST", "RequestFramer"]

#: Longest request line taken (bytes, terminator excluded): ``MD`` + 13 digits + ``;`` +
#: 16 string characters is 32; a sensor's buffer is not much larger.
MAX_REQUEST = 64


class RequestFramer:
    """Splits a byte stream into request lines (without their terminator)."""

    def __init__(self, max_line: int = MAX_REQUEST) -> None:
        self.max_line = max_line
        self._buf = bytearray()
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

    @property
    def pending(self) -> int:
        """Bytes of a request not yet terminated."""
        return len(self._buf)

    def reset(self) -> None:
        """Forget the partial line (the counters are kept)."""
        self._buf.clear()
        self._after_cr = self._skipping = False

    @property
    def stats(self) -> FramerStats:
        return FramerStats(self._frames, self._dropped, 0, self._oversize)
