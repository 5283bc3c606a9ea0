"""MCAP files built record by record, for the tests of what a damaged or hostile file does
to robocli's readers: the records are the ``mcap`` package's own, a chunk's data anything
(a zstd frame made of run-length blocks inflates to a gigabyte from 32 KB)."""

from __future__ import annotations

import struct
from typing import Any

from mcap.data_stream import RecordBuilder
from mcap.records import Channel, Chunk, DataEnd, Footer, Header, Message, Schema

MAGIC = b"\x89MCAP0\r\n"
_BLOCK = 1 << 17  # zstd's largest block (bytes)


def records(*items: Any) -> bytes:
    """The bytes of ``items`` (``mcap`` records, or bytes as they are), in order."""
    out = bytearray()
    for item in items:
        if isinstance(item, (bytes, bytearray)):
            out += item
            continue
        builder = RecordBuilder()
        item.write(builder)
        out += builder.end()
    return bytes(out)


def mcap(*items: Any, closed: bool = True) -> bytes:
    """A file: the magic, a Header, ``items``, and when ``closed`` a DataEnd, a Footer
    without summary and the magic."""
    body = records(Header(profile="", library="tests"), *items)
    tail = records(DataEnd(0), Footer(0, 0, 0)) + MAGIC if closed else b""
    return MAGIC + body + tail


def schema_and_channel(topic: str = "/t", encoding: str = "json") -> list[Any]:
    return [
        Schema(id=1, name="s", encoding="jsonschema", data=b"{}"),
        Channel(id=1, schema_id=1, topic=topic, message_encoding=encoding, metadata={}),
    ]


def message_head(data_len: int, channel_id: int = 1, t: int = 1) -> bytes:
    """A Message record's opcode, length and fields, its ``data_len`` bytes of data left to
    follow."""
    return struct.pack("<BQHIQQ", 0x05, 22 + data_len, channel_id, 0, t, t)


def zstd_rle(prefix: bytes, zeros: int, content_size: int | None = None) -> bytes:
    """A zstd frame of ``prefix`` (a raw block) then ``zeros`` zero bytes as run-length
    blocks of 4 bytes each; the frame header declares ``content_size`` when given."""

    def block(last: bool, kind: int, size: int) -> bytes:
        return (int(last) | kind << 1 | size << 3).to_bytes(3, "little")

    if content_size is None:
        out = bytearray(b"\x28\xb5\x2f\xfd\x00\x38")  # no content size; a 128 KiB window
    else:  # 8-byte content size (flag 3), single segment: no window descriptor
        out = bytearray(b"\x28\xb5\x2f\xfd\xe0") + struct.pack("<Q", content_size)
    out += block(zeros == 0, 0, len(prefix)) + prefix
    left = zeros
    while left:
        n = min(left, _BLOCK)
        left -= n
        out += block(left == 0, 1, n) + b"\0"
    return bytes(out)


def zstd_chunk(content: bytes, zeros: int = 0, declared: int | None = None,
               content_size: int | None = None) -> Chunk:  # fmt: skip
    """A zstd Chunk of ``content`` then ``zeros`` zero bytes, declaring ``declared`` bytes
    uncompressed (default: the truth)."""
    real = len(content) + zeros
    return Chunk(compression="zstd", data=zstd_rle(content, zeros, content_size),
                 message_start_time=1, message_end_time=1, uncompressed_crc=0,
                 uncompressed_size=real if declared is None else declared)  # fmt: skip


def plain_chunk(*items: Any) -> Chunk:
    """An uncompressed Chunk holding ``items``."""
    data = records(*items)
    return Chunk(compression="", data=data, message_start_time=1, message_end_time=1,
                 uncompressed_crc=0, uncompressed_size=len(data))  # fmt: skip


def message(data: bytes = b"{}", channel_id: int = 1, t: int = 1) -> Message:
    return Message(channel_id=channel_id, sequence=0, log_time=t, publish_time=t, data=data)
