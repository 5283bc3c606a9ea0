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
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import Any

__all__ = ["MessageAdder"]

#: opcode, record length, channel id, sequence, log time, publish time
_HEAD = struct.Struct("<BQHIQQ")
_MESSAGE = 0x05
_MESSAGE_INDEX = 0x07
_FIXED = _HEAD.size - 9  # the record's length counts what follows opcode and length


class MessageAdder:
    """``add(channel_id, log_time, data, publish_time, sequence)`` for ``writer``, as its
    ``add_message`` (see the module docstring). ``fast``: whether the one-step path is used."""

    def __init__(self, writer: Any) -> None:
        self._writer = writer
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
        self.add = self._add if self.fast else writer.add_message

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
        if buffer.tell() > self._chunk_size:
            self._finalize()


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
