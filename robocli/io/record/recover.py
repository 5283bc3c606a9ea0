"""Rewriting a recording cut short into one every MCAP reader opens (``robocli recover``).

A recording killed with SIGKILL, or whose disk filled up, ends inside a record and has no
summary, footer or closing magic: robocli reads it up to its last complete record, but the
``mcap`` package's ``make_reader`` and the viewers refuse it. :func:`recover` reads every
complete record of such a file (as ``mcap recover`` does) and writes them into a new file
with the ``mcap`` package's writer, which adds the chunk and message indexes, the
statistics, the summary and the footer:

>>> from robocli.io.record import recover                  # doctest: +SKIP
>>> recover("killed.mcap", "whole.mcap")
RecoverStats(messages=2258, ...)

Schemas, channels (topic, encoding, metadata), messages (log and publish times, sequence,
data, in file order), attachments and metadata records are kept; ids are renumbered in the
order met. A chunk that does not decompress, or whose CRC fails, is skipped and counted
(its neighbours are kept); so is any other malformed record whose length still fits the
file. The output is chunked with the input's first compression (zstd for a file without
chunks).

The input is never written to. The output is refused when it is the input, when it is a
symbolic link, and when it exists unless ``overwrite`` is given; it is written beside its
final name and renamed into place once complete, so a failure leaves no partial file.
"""

from __future__ import annotations

import contextlib
import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from robocli._version import __version__
from robocli.io.record.mcapfile import BadRecording, McapFile
from robocli.output import OutputError, check_output, replace_output

log = logging.getLogger("robocli.io.record")

__all__ = ["RecoverStats", "default_output", "recover"]


@dataclass
class RecoverStats:
    """What :func:`recover` read and wrote."""

    path: str  #: the file written
    messages: int = 0
    schemas: int = 0
    channels: int = 0
    chunks: int = 0  #: complete chunks read
    attachments: int = 0
    metadata: int = 0
    skipped: int = 0  #: malformed chunks and records left out
    orphans: int = 0  #: messages of a channel never declared, left out
    truncated: bool = False  #: the input ended before its footer
    lost_bytes: int = 0  #: bytes after the last complete record (a cut record)

    def as_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


def default_output(path: str | Path) -> Path:
    """``NAME.recovered.mcap`` beside ``path``."""
    src = Path(path)
    return src.with_name(f"{src.stem}.recovered{src.suffix or '.mcap'}")


def _check_output(src: Path, out: Path, overwrite: bool) -> None:
    """Refuse an output that is the input (under any name), then as every output is refused
    (:func:`~robocli.output.check_output`: a symbolic link, a folder, an existing file
    without ``overwrite``)."""
    with contextlib.suppress(OSError):
        if out.samefile(src):
            raise OutputError(f"{out} is the recording being recovered: give another output")
    check_output(out, overwrite)


def recover(path: str | Path, out: str | Path | None = None, *,
            overwrite: bool = False) -> RecoverStats:  # fmt: skip
    """Rewrite the recording at ``path`` whole into ``out`` (default
    :func:`default_output`); see the module docstring. Raises :class:`BadRecording` for an
    input that is not MCAP or holds no complete record, and
    :class:`~robocli.output.OutputError` for an output it may not or cannot write."""
    from mcap.records import Header

    src, dst = Path(path), Path(out) if out is not None else default_output(path)
    _check_output(src, dst, overwrite)
    with McapFile(src) as f:
        first = f.header()
        if not isinstance(first, Header):
            raise BadRecording(f"{src} has no complete header record: nothing to recover")
        stats = RecoverStats(str(dst))
        with replace_output(dst, overwrite) as stream:  # beside it, in place once whole
            _copy(f, first, stream, stats)
    log.info("recovered %s into %s: %s", src, dst, stats)
    return stats


def _copy(f: McapFile, header: Any, stream: Any, stats: RecoverStats) -> None:
    """Every complete record of ``f`` into a new MCAP on ``stream``."""
    from mcap.records import Attachment, Channel, Message, Metadata, Schema

    from robocli.io.record.fastwrite import MessageAdder

    writer: Any = None
    add: Any = None
    schema_ids: dict[int, int] = {}
    channel_ids: dict[int, int] = {}
    for offset, opcode, length in f.spans():
        if opcode not in (0x03, 0x04, 0x05, 0x06, 0x09, 0x0C):  # indexes, header: rebuilt
            continue
        try:
            records = f.parse(offset, opcode, length)
        except BadRecording as exc:
            stats.skipped += 1
            log.warning("recover: %s; left out", exc)
            continue
        if writer is None:  # the first chunk's compression is known now
            writer = _writer(stream, header, f.compressions)
            add = MessageAdder(writer).add
        for rec in records:
            if isinstance(rec, Message):
                cid = channel_ids.get(rec.channel_id)
                if cid is None:
                    stats.orphans += 1
                    continue
                add(cid, rec.log_time, rec.data, rec.publish_time, rec.sequence)
                stats.messages += 1
            elif isinstance(rec, Schema) and rec.id not in schema_ids and rec.id:
                schema_ids[rec.id] = writer.register_schema(rec.name, rec.encoding, rec.data)
                stats.schemas += 1
            elif isinstance(rec, Channel) and rec.id not in channel_ids:
                channel_ids[rec.id] = writer.register_channel(
                    rec.topic, rec.message_encoding, schema_ids.get(rec.schema_id, 0),
                    rec.metadata)  # fmt: skip
                stats.channels += 1
            elif isinstance(rec, Attachment):
                writer.add_attachment(rec.create_time, rec.log_time, rec.name, rec.media_type,
                                      rec.data)  # fmt: skip
                stats.attachments += 1
            elif isinstance(rec, Metadata):
                writer.add_metadata(rec.name, rec.metadata)
                stats.metadata += 1
    if writer is None:  # nothing after the header: an empty recording
        writer = _writer(stream, header, [])
    writer.finish()
    stats.chunks = f.chunks
    stats.truncated = f.truncated
    stats.lost_bytes = f.size - f.readable_bytes if f.truncated else 0


def _writer(stream: Any, header: Any, compressions: list[str]) -> Any:
    """An ``mcap`` writer started on ``stream``, compressing as the input's first chunk."""
    from mcap.writer import CompressionType, Writer

    kind = compressions[0] if compressions else "zstd"
    compression = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4}.get(
        kind, CompressionType.NONE)  # fmt: skip
    writer = Writer(stream, chunk_size=4 << 20, compression=compression)
    writer.start(
        profile=header.profile, library=f"{header.library}; recovered by robocli {__version__}"
    )
    return writer
