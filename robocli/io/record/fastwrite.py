"""Messages added to an ``mcap`` :class:`~mcap.writer.Writer`'s chunk in one step each.

The mcap package writes a Message record field by field (a ``struct.pack`` and a buffer
write per field, a record object, the size patched afterwards), and each entry of a chunk's
message indexes likewise: about 3.5 us per message, the largest part of what recording a
Pioneer SIP cost the writer thread (5 messages per SIP). :class:`MessageAdder` does what
``Writer.add_message`` does to the writer's state (the statistics, the chunk's time range
and message index) and writes the record with one ``struct.pack`` of its 31-byte head and
one write of its data; its message indexes are written with one ``struct.pack`` each. The
bytes are the same, which a test checks against the package's own writer.

It reaches into the writer's private state; a writer without that state (another version
of the package) is served by its public ``add_message`` instead.

It also keeps the ledger of chunks a recorder needs to say what its file holds:
:attr:`MessageAdder.chunks` lists, for each chunk handed to the stream and not yet counted,
where it ends in the file and how many messages it holds; :class:`WrittenBytes` counts the
bytes that reached the file (each write a system call, no buffer in between), so that after
a failed write the chunks within them are exactly those a reader finds.
"""

from __future__ import annotations

import io
import os
import struct
from collections import deque
from collections.abc import Callable
from typing import Any

__all__ = ["MessageAdder", "WrittenBytes"]

#: opcode, record length, channel id, sequence, log time, publish time
_HEAD = struct.Struct("<BQHIQQ")
_MESSAGE = 0x05
_MESSAGE_INDEX = 0x07
_FIXED = _HEAD.size - 9  # the record's length counts what follows opcode and length


class MessageAdder:
    """``add(channel_id, log_time, data, publish_time, sequence)`` for ``writer``, as its
    ``add_message`` (see the module docstring). ``fast``: whether the one-step path is used."""

    def __init__(self, writer: Any, tell: Callable[[], int] | None = None) -> None:
        self._writer = writer
        self._tell = tell
        #: messages in the chunk being built
        self.in_chunk = 0
        #: where the file ended when the chunk being built was handed to it (``tell``'s
        #: value), or -1: a write that failed after the chunk's own record was whole
        #: (in its message indexes) leaves that chunk readable (see :func:`chunk_is_whole`)
        self.chunk_start = -1
        #: (end offset in the file or -1 when unknown, messages) of the chunks handed to the
        #: stream and not yet counted by the recorder
        self.chunks: deque[tuple[int, int]] = deque()
        self._indexes: list[Any] | None = getattr(writer, "_Writer__chunk_indices", None)
        self._known = len(self._indexes) if self._indexes is not None else 0
        try:
            self._stats = writer._Writer__statistics
            self._builder = writer._Writer__chunk_builder
            self._finalize: Callable[[], None] = writer._Writer__maybe_finalize_chunk
            self._chunk_size: int = writer._Writer__chunk_size
            self._index = _index_class()
            self.fast = (self._builder is not None
                         and hasattr(self._builder.record_writer, "_buffer")
                         and hasattr(self._stats, "channel_message_counts"))  # fmt: skip
        except (AttributeError, ImportError):
            self.fast = False
        self.add = self._add if self.fast else self._add_slowly

    def flush(self) -> None:
        """Close the chunk in progress and write out what the writer holds (its ``flush``)."""
        self._mark()
        self._writer.flush()
        self._chunk_closed()

    def _mark(self) -> None:
        self.chunk_start = self._tell() if self._tell is not None else -1

    def _chunk_closed(self) -> None:
        """Enter the chunk just written (if one was) in :attr:`chunks`."""
        indexes = self._indexes
        if indexes is None:
            if self.in_chunk:  # where it ends is unknown: counted once flushed
                self.chunks.append((-1, self.in_chunk))
                self.in_chunk = 0
            return
        if len(indexes) != self._known:
            self._known = len(indexes)
            last = indexes[-1]
            self.chunks.append((last.chunk_start_offset + last.chunk_length, self.in_chunk))
            self.in_chunk = 0

    def _add_slowly(self, *args: Any) -> None:
        self._mark()
        self._writer.add_message(*args)
        self.in_chunk += 1
        self._chunk_closed()

    def _add(self, channel_id: int, log_time: int, data: bytes, publish_time: int,
             sequence: int = 0) -> None:  # fmt: skip
        stats = self._stats
        if stats.message_count == 0 or log_time < stats.message_start_time:
            stats.message_start_time = log_time
        if log_time > stats.message_end_time:
            stats.message_end_time = log_time
        counts = stats.channel_message_counts
        counts[channel_id] = counts.get(channel_id, 0) + 1
        stats.message_count += 1
        builder = self._builder
        if builder.num_messages == 0 or log_time < builder.message_start_time:
            builder.message_start_time = log_time
        if log_time > builder.message_end_time:
            builder.message_end_time = log_time
        buffer = builder.record_writer._buffer  # a new one after each chunk
        index = builder.message_indices.get(channel_id)
        if not index:
            index = builder.message_indices[channel_id] = self._index(channel_id, [])
        index.records.append((log_time, buffer.tell()))
        builder.num_messages += 1
        buffer.write(_HEAD.pack(_MESSAGE, _FIXED + len(data), channel_id, sequence, log_time,
                                publish_time))  # fmt: skip
        buffer.write(data)
        self.in_chunk += 1
        if buffer.tell() > self._chunk_size:
            self._mark()
            self._finalize()
            self._chunk_closed()


_CHUNK = 0x06
_RECORD = struct.Struct("<BQ")


def chunk_is_whole(fd: int, start: int, size: int) -> bool:
    """Whether the first Chunk record at or after ``start`` in the file ``fd`` (records
    before it skipped) ends within its first ``size`` bytes."""
    pos = start
    while 0 <= pos and pos + _RECORD.size <= size:
        opcode, length = _RECORD.unpack(os.pread(fd, _RECORD.size, pos))
        end = pos + _RECORD.size + length
        if opcode == _CHUNK:
            return bool(end <= size)
        pos = end
    return False


class WrittenBytes:
    """A file the mcap writer writes straight into: each ``write`` is written whole with
    system calls (no buffer that a later flush might or might not empty), and
    :attr:`written` is how many bytes the file holds. Not a :class:`io.RawIOBase`, so that
    the writer does not buffer it again."""

    def __init__(self, raw: io.FileIO) -> None:
        self._raw = raw
        self.name = raw.name
        self.written = 0

    def write(self, data: bytes | bytearray | memoryview) -> int:
        view = memoryview(data).cast("B")
        while view:
            n = self._raw.write(view)
            if not n:  # pragma: no cover - a regular file does not refuse without an error
                raise OSError(f"{self.name}: nothing written")
            self.written += n
            view = view[n:]
        return len(data)

    def tell(self) -> int:
        return self.written

    def flush(self) -> None:
        """Nothing is buffered here."""

    def fileno(self) -> int:
        return self._raw.fileno()

    def close(self) -> None:
        self._raw.close()

    @property
    def closed(self) -> bool:
        return self._raw.closed


def _index_class() -> type:
    """mcap's MessageIndex, written in one ``struct.pack`` (the same bytes)."""
    from itertools import chain

    from mcap.records import MessageIndex

    class FastIndex(MessageIndex):
        def write(self, stream: Any) -> None:
            n = len(self.records)
            stream.write(struct.pack(f"<BQHI{2 * n}Q", _MESSAGE_INDEX, 6 + 16 * n,
                                     self.channel_id, 16 * n,
                                     *chain.from_iterable(self.records)))  # fmt: skip

    return FastIndex
