"""Reading recordings back: ``robocli info``'s summary, and the raw frames ``dump --file``
decodes.

A finished recording ends with a summary (statistics, channels, chunk indexes, and after
each chunk its message indexes): :func:`info` reads those and never decompresses a chunk,
so a large file is summarised in the time of a few thousand small reads. A recording that
was killed has no summary: :func:`info` then scans it from the start, record by record,
and stops at the first incomplete record (what a SIGKILL leaves is readable up to its last
complete chunk), saying so; the other readers log :func:`~.mcapfile.warn_truncated`, which
the CLI prints as a note naming ``robocli recover``. Every length the file declares is
checked before it is read (:mod:`.mcapfile`): a malformed file raises
:class:`~.mcapfile.BadRecording`.
"""

from __future__ import annotations

import base64
import binascii
import heapq
import json
import logging
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from robocli.errors import RobocliError
from robocli.io.record.links import RAW_ENCODING, ROS2_RAW_TYPE, is_raw
from robocli.io.record.mcapfile import BadRecording, McapFile, warn_truncated
from robocli.io.record.recorder import RecordingError

log = logging.getLogger("robocli.io.record")

__all__ = ["ChannelInfo", "RecordingInfo", "info", "iter_messages", "raw_frames"]


@dataclass
class ChannelInfo:
    """One channel of a recording: counts and times from its messages' log times."""

    id: int
    topic: str
    schema: str
    encoding: str
    metadata: dict[str, str]
    count: int = 0
    first_ns: int = 0
    last_ns: int = 0
    largest_gap_s: float = 0.0

    @property
    def rate_hz(self) -> float | None:
        """Mean rate over the channel's own span: (count - 1) / (last - first)."""
        span = (self.last_ns - self.first_ns) / 1e9
        return (self.count - 1) / span if self.count > 1 and span > 0 else None

    def as_dict(self) -> dict[str, Any]:
        return {
            "topic": self.topic, "schema": self.schema, "encoding": self.encoding,
            "count": self.count, "rate_hz": self.rate_hz, "largest_gap_s": self.largest_gap_s,
            "first": self.first_ns / 1e9, "last": self.last_ns / 1e9, "metadata": self.metadata,
        }  # fmt: skip


@dataclass
class RecordingInfo:
    """What :func:`info` found. Times are Unix-epoch nanoseconds (``start_ns``, ``end_ns``)."""

    path: str
    size: int
    library: str = ""
    summary: bool = False  #: the file has a summary section (it was closed properly)
    truncated: bool = False  #: no summary, and the scan met an incomplete record
    readable_bytes: int = 0  #: bytes up to the last complete record
    messages: int = 0
    chunks: int = 0
    compression: list[str] = field(default_factory=list)
    start_ns: int = 0
    end_ns: int = 0
    channels: list[ChannelInfo] = field(default_factory=list)

    @property
    def duration_s(self) -> float:
        return max(0, self.end_ns - self.start_ns) / 1e9

    def as_dict(self) -> dict[str, Any]:
        return {
            "path": self.path, "bytes": self.size, "library": self.library,
            "summary": self.summary, "truncated": self.truncated,
            "readable_bytes": self.readable_bytes, "messages": self.messages,
            "chunks": self.chunks, "compression": self.compression,
            "start": self.start_ns / 1e9 if self.messages else None,
            "end": self.end_ns / 1e9 if self.messages else None,
            "duration_s": self.duration_s,
            "channels": [c.as_dict() for c in self.channels],
        }  # fmt: skip


def info(path: str | Path) -> RecordingInfo:
    """Summarise the recording at ``path`` (see the module docstring). Raises
    :class:`~robocli.io.record.mcapfile.BadRecording` for a file that is not MCAP or is
    malformed, :class:`RobocliError` for one that cannot be read."""
    with McapFile(path) as f:
        result = RecordingInfo(str(path), f.size)
        try:
            summary = f.summary()
        except BadRecording as exc:  # the data may still read: scan it
            log.info("%s; scanning the file instead", exc)
            summary = None
        if summary is not None and _indexed(summary) and _from_summary(f, summary, result):
            return result
        _scan(f, result)
        return result


def _indexed(summary: Any) -> bool:
    """Whether the summary says where every message is: chunk indexes, or no message."""
    stats = summary.statistics
    return bool(summary.chunk_indexes) or (stats is not None and stats.message_count == 0)


#: MCAP record opcodes read here without the mcap package's record classes.
_OP_MESSAGE_INDEX = 0x07
_RECORD_HEAD = struct.Struct("<BQ")
_INDEX_HEAD = struct.Struct("<HI")


def _message_indexes(block: bytes) -> Iterator[tuple[int, Any]]:
    """(channel id, uint64 array of log time, offset pairs flattened) of each Message Index
    record in ``block`` (the records that follow a chunk), each bounded by the block."""
    import numpy as np

    pos = 0
    while pos + _RECORD_HEAD.size <= len(block):
        opcode, length = _RECORD_HEAD.unpack_from(block, pos)
        pos += _RECORD_HEAD.size
        length = min(length, len(block) - pos)
        if opcode == _OP_MESSAGE_INDEX and length >= _INDEX_HEAD.size:
            channel_id, size = _INDEX_HEAD.unpack_from(block, pos)
            count = min(size, length - _INDEX_HEAD.size) // 16
            pairs = np.frombuffer(block, dtype="<u8", count=2 * count,
                                  offset=pos + _INDEX_HEAD.size)  # fmt: skip
            yield channel_id, pairs
        pos += length


def _times(channel: ChannelInfo, times: list[Any]) -> None:
    """Fill ``channel``'s count, first, last and largest gap from its log times (ints or
    arrays of them, uint64 nanoseconds)."""
    import numpy as np

    if not times:
        return
    parts = [np.asarray(t, dtype=np.uint64).ravel() for t in times]
    arr = np.sort(np.concatenate(parts)) if len(parts) > 1 else np.sort(parts[0])
    if not arr.size:
        return
    channel.count = int(arr.size)
    channel.first_ns, channel.last_ns = int(arr[0]), int(arr[-1])
    channel.largest_gap_s = float(np.max(np.diff(arr))) / 1e9 if arr.size > 1 else 0.0


def _from_summary(f: McapFile, summary: Any, result: RecordingInfo) -> bool:
    """Fill ``result`` from the summary and the message indexes; False when the file has no
    message indexes, or they are not where the summary says (then it is scanned)."""

    times: dict[int, list[Any]] = {cid: [] for cid in summary.channels}
    for chunk in summary.chunk_indexes:
        if not chunk.message_index_offsets:
            return False
        start = min(chunk.message_index_offsets.values())
        if start + chunk.message_index_length > f.size:
            return False  # the summary points past the end: scan instead
        block = f.read_at(start, chunk.message_index_length)
        for channel_id, records in _message_indexes(block):
            times.setdefault(channel_id, []).append(records[0::2].copy())
        if chunk.compression and chunk.compression not in result.compression:
            result.compression.append(chunk.compression)
    result.summary = True
    result.readable_bytes = result.size
    result.chunks = len(summary.chunk_indexes)
    stats = summary.statistics
    if stats is not None:
        result.messages = stats.message_count
        result.start_ns, result.end_ns = stats.message_start_time, stats.message_end_time
    for cid, channel in sorted(summary.channels.items()):
        schema = summary.schemas.get(channel.schema_id)
        item = ChannelInfo(cid, channel.topic, schema.name if schema else "",
                           channel.message_encoding, dict(channel.metadata))  # fmt: skip
        _times(item, times.get(cid, []))
        result.channels.append(item)
    if stats is None:
        result.messages = sum(c.count for c in result.channels)
        firsts = [c.first_ns for c in result.channels if c.count]
        result.start_ns = min(firsts, default=0)
        result.end_ns = max((c.last_ns for c in result.channels if c.count), default=0)
    header = f.header()
    result.library = header.library if header is not None else ""
    return True


def iter_messages(path: str | Path) -> Iterator[Any]:
    """Every Schema, Channel and Message record of the recording at ``path`` in file order,
    chunks opened; a file cut short is read up to its last complete record, and a warning
    says so (:func:`~robocli.io.record.mcapfile.truncated_hint`)."""
    with McapFile(path) as f:
        yield from f.records(skip=_NOT_DATA)
        if f.truncated:
            warn_truncated(path)


#: What readers of messages step over unparsed: indexes, attachments, metadata.
_NOT_DATA = frozenset((0x07, 0x08, 0x09, 0x0A, 0x0B, 0x0C, 0x0D, 0x0E))


def _scan(f: McapFile, result: RecordingInfo) -> None:
    from mcap.records import Channel, Header, Message, Schema

    schemas: dict[int, str] = {}
    channels: dict[int, ChannelInfo] = {}
    times: dict[int, list[Any]] = {}
    for rec in f.records(skip=_NOT_DATA):
        if isinstance(rec, Header):
            result.library = rec.library
        elif isinstance(rec, Schema):
            schemas[rec.id] = rec.name
        elif isinstance(rec, Channel) and rec.id not in channels:
            schema = schemas.get(rec.schema_id, "")
            channels[rec.id] = ChannelInfo(rec.id, rec.topic, schema, rec.message_encoding,
                                           dict(rec.metadata))  # fmt: skip
        elif isinstance(rec, Message):
            times.setdefault(rec.channel_id, []).append(rec.log_time)
    result.truncated = f.truncated
    result.chunks, result.compression = f.chunks, list(f.compressions)
    result.readable_bytes = min(f.readable_bytes, result.size)
    for cid, channel in sorted(channels.items()):
        _times(channel, times.get(cid, []))
        result.channels.append(channel)
    result.messages = sum(c.count for c in result.channels)
    result.start_ns = min((c.first_ns for c in result.channels if c.count), default=0)
    result.end_ns = max((c.last_ns for c in result.channels if c.count), default=0)


# ---------------------------------------------------------------------- raw frames


def _family(protocol: str) -> str:
    return "sm" if protocol.startswith("sm") else protocol


#: How far (ns) a message may come before an older one in a file without summary: frames
#: sent and received in different threads are queued in about their time order.
_REORDER_NS = 2_000_000_000


def raw_frames(path: str | Path, protocol: str, stats: Any = None
               ) -> Iterator[tuple[float, str, bytes]]:  # fmt: skip
    """The frames of the raw channels of one link speaking ``protocol`` (``arcos``,
    ``sm-le``/``sm-be``: either byte order, ``ros4mat``, ``scip2``), in log-time order, as
    ``(t, direction, frame)``: ``t`` in seconds since the first message of the recording,
    ``direction`` ``tx``/``rx`` with ``:port`` for an arm link (what
    :func:`robocli.io.capture.read_capture` makes its frames of). With several such links
    the first is read and the others are named in a warning log. ``stats`` (a
    :class:`~robocli.io.capture.CaptureStats`, optional) is updated as it goes. ``scip2``
    (a Hokuyo): reply blocks on ``rx``, request lines (without their terminator) on ``tx``."""
    summary_info = info(path)
    raws = [c for c in summary_info.channels if is_raw(c.encoding, c.schema)
            and _family(c.metadata.get("protocol", "")) == _family(protocol)]  # fmt: skip
    links = list(dict.fromkeys(c.metadata.get("link", "") for c in raws))
    if not links:
        found = sorted({c.metadata.get("protocol", "?") for c in summary_info.channels
                        if is_raw(c.encoding, c.schema)})  # fmt: skip
        raise RobocliError(f"{path}: no raw {protocol} channel (raw channels: "
                           f"{', '.join(found) or 'none'})")  # fmt: skip
    if len(links) > 1:
        log.warning("%s: %d %s links (%s); decoding %s", path, len(links), protocol,
                    ", ".join(links), links[0])  # fmt: skip
    chosen = {c.id: c for c in raws if c.metadata.get("link") == links[0]}
    start = summary_info.start_ns
    if stats is not None:
        stats.start_unix = start / 1e9
    framers: dict[int, Any] = {}
    try:
        for channel_id, log_ns, data in _ordered(path, summary_info, set(chosen)):
            channel = chosen[channel_id]
            data = raw_frame(channel.encoding, data)
            meta = channel.metadata
            framer = framers.get(channel_id)
            if framer is None:
                framer = framers[channel_id] = _framer(meta.get("protocol", protocol),
                                                       meta.get("direction", ""))  # fmt: skip
            if stats is not None:
                stats.bytes_read += len(data)
            way = meta.get("direction", "?")
            if meta.get("port"):
                way = f"{way}:{meta['port']}"
            for frame in framer.feed(data):
                if stats is not None:
                    stats.frames += 1
                yield (log_ns - start) / 1e9, way, frame
    finally:
        if stats is not None:
            for framer in framers.values():
                stats.dropped_bytes += framer.stats.dropped_bytes + framer.pending


def raw_frame(encoding: str, data: bytes) -> bytes:
    """The frame a raw channel's message holds: ``data`` itself for :data:`RAW_ENCODING`,
    the ``data`` of a ROS 2 bag's ``robocli_msgs/msg/RawFrame`` (CDR), else the base64
    ``data`` of the JSON. Raises :class:`RecordingError` for a message that has none."""
    if encoding == RAW_ENCODING:
        return data
    if encoding == "cdr":
        from robocli.ros2.types import deserialize

        try:
            return bytes(deserialize(data, ROS2_RAW_TYPE).data)
        except RobocliError as exc:
            raise RecordingError(f"a raw frame's message is malformed ({exc})") from None
    try:
        text = json.loads(data)["data"]
        return base64.b64decode(text, validate=True)
    except (ValueError, KeyError, TypeError, binascii.Error) as exc:
        raise RecordingError(f"a raw frame's message is malformed ({exc})") from None


def _framer(protocol: str, direction: str) -> Any:
    """The framer of one raw channel: the protocol's C framer, except for what a SCIP
    client sends (request lines, framed as the simulator frames them)."""
    if protocol == "scip2" and direction == "tx":
        from robocli.protocols.scip2.framing import RequestFramer

        return RequestFramer()
    from robocli.core import Framer

    return Framer(protocol)


def _ordered(path: str | Path, summary_info: RecordingInfo,
             channels: set[int]) -> Iterator[tuple[int, int, bytes]]:  # fmt: skip
    """(channel id, log time, data) of ``channels``' messages in log-time order: merged by
    the chunk indexes of a finished file, within :data:`_REORDER_NS` in one cut short."""
    from mcap.records import Message

    heap: list[tuple[int, int, int, bytes]] = []
    seq = 0
    with McapFile(path) as f:
        summary = f.summary() if summary_info.summary else None
        if summary is not None and summary.chunk_indexes:
            # a message of a later chunk is no older than its chunk's start
            for chunk in sorted(
                summary.chunk_indexes, key=lambda c: (c.message_start_time, c.chunk_start_offset)
            ):
                while heap and heap[0][0] < chunk.message_start_time:
                    t, _, cid, data = heapq.heappop(heap)
                    yield cid, t, data
                for record in f.chunk_at(chunk.chunk_start_offset, chunk.chunk_length):
                    if isinstance(record, Message) and record.channel_id in channels:
                        heapq.heappush(heap, (record.log_time, seq, record.channel_id,
                                              record.data))  # fmt: skip
                        seq += 1
        else:
            for record in f.records(skip=_NOT_DATA):
                if isinstance(record, Message) and record.channel_id in channels:
                    heapq.heappush(heap, (record.log_time, seq, record.channel_id, record.data))
                    seq += 1
                    while heap and heap[0][0] < record.log_time - _REORDER_NS:
                        t, _, cid, data = heapq.heappop(heap)
                        yield cid, t, data
            if f.truncated:
                warn_truncated(path)
    while heap:
        t, _, cid, data = heapq.heappop(heap)
        yield cid, t, data
