"""The Open Interface's two byte streams, framed: the commands a robot receives
(:class:`CommandFramer`) and the sensor stream a client receives (:class:`StreamFramer`).

The OI has no sync marker: a command is its opcode and as many data bytes as the opcode
says (:func:`~robocli.protocols.create_oi.commands.command_length`). A byte where an opcode
should be that is none, and a song whose number or length is out of range, is dropped (one
byte, counted) and the scan goes on from the next byte, so garbage costs the commands it
overlaps and no more. A command is at most
:data:`~robocli.protocols.create_oi.commands.MAX_COMMAND` bytes: the buffer never holds more.
Same interface as :class:`robocli.core.Framer` (``feed``, ``pending``, ``reset``, ``stats``),
so the simulators' serving layer uses it as it uses the C framers.
"""

from __future__ import annotations

from robocli.core import FramerStats
from robocli.errors import ProtocolError
from robocli.protocols.common import PartialFrame
from robocli.protocols.create_oi.commands import command_length
from robocli.protocols.create_oi.sensors import STREAM_HEADER

__all__ = ["CommandFramer", "StreamFramer"]


class _Scanner(PartialFrame):
    """What both framers share: a bounded buffer scanned from its start, a byte that cannot
    start a frame dropped and counted, the counters. :meth:`_length` says, at ``pos``, how
    long the frame there is (None: wait for more bytes; 0: drop this byte)."""

    _BAD_IS_CHECKSUM = False  # whether ``_bad`` counts checksums or length fields

    def __init__(self) -> None:
        super().__init__()
        self._frames = 0
        self._dropped = 0
        self._bad = 0

    def _length(self, buf: bytearray, pos: int) -> int | None:  # pragma: no cover - abstract
        raise NotImplementedError

    def feed(self, data: bytes | bytearray | memoryview) -> list[bytes]:
        """Append ``data``; every frame now complete, in order."""
        buf = self._buf
        buf += data
        out: list[bytes] = []
        pos = 0
        while pos < len(buf):
            n = self._length(buf, pos)
            if n == 0:
                self._dropped += 1
                pos += 1
                continue
            if n is None or pos + n > len(buf):
                break
            out.append(bytes(buf[pos : pos + n]))
            pos += n
        del buf[:pos]
        self._frames += len(out)
        return out

    @property
    def stats(self) -> FramerStats:
        """Frames, bytes dropped, bad checksums, bad lengths."""
        if self._BAD_IS_CHECKSUM:
            return FramerStats(self._frames, self._dropped, self._bad, 0)
        return FramerStats(self._frames, self._dropped, 0, self._bad)


class CommandFramer(_Scanner):
    """Splits a byte stream into whole OI commands (opcode first); ``stats.bad_lengths``
    counts the songs refused for their number or length (the OI has no checksums)."""

    def _length(self, buf: bytearray, pos: int) -> int | None:
        try:
            return command_length(buf[pos : pos + 3])
        except ProtocolError:
            if buf[pos] == 140:  # a song with an impossible number or length
                self._bad += 1
            return 0


class StreamFramer(_Scanner):
    """Splits the robot's output into whole stream frames (opcode 148's: 19, n, n bytes,
    checksum). A byte where a header should be that is not 19 is dropped and counted; a frame
    whose checksum is wrong counts as a bad checksum and only its header byte is dropped, the
    rest rescanned (a 19 inside a frame's data is found out by its checksum). A frame is at
    most 258 bytes: the buffer never holds more. Same interface as
    :class:`robocli.core.Framer`."""

    _BAD_IS_CHECKSUM = True

    def _length(self, buf: bytearray, pos: int) -> int | None:
        if buf[pos] != STREAM_HEADER:
            return 0
        if pos + 2 > len(buf) or pos + 3 + buf[pos + 1] > len(buf):
            return None
        n = 3 + buf[pos + 1]
        if sum(buf[pos : pos + n]) & 0xFF:
            self._bad += 1
            return 0
        return n
