"""The Open Interface's command stream, framed (:class:`CommandFramer`).

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
from robocli.protocols.create_oi.commands import command_length

__all__ = ["CommandFramer"]


class CommandFramer:
    """Splits a byte stream into whole OI commands (opcode first)."""

    def __init__(self) -> None:
        self._buf = bytearray()
        self._frames = 0
        self._dropped = 0
        self._bad = 0  # commands refused for their length fields (songs)

    def feed(self, data: bytes | bytearray | memoryview) -> list[bytes]:
        """Append ``data``; every command now complete, in order."""
        buf = self._buf
        buf += data
        out: list[bytes] = []
        pos = 0
        while pos < len(buf):
            try:
                n = command_length(buf[pos : pos + 3])
            except ProtocolError:
                if buf[pos] in (140,):  # a song with an impossible number or length
                    self._bad += 1
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
    def pending(self) -> int:
        """Bytes of a command not complete yet."""
        return len(self._buf)

    def reset(self) -> None:
        """Forget the partial command (the counters are kept)."""
        self._buf.clear()

    @property
    def stats(self) -> FramerStats:
        """Commands framed, bytes dropped, 0 checksums (the OI has none), songs refused."""
        return FramerStats(self._frames, self._dropped, 0, self._bad)
