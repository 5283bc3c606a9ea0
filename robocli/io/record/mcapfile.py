"""MCAP files read with every length checked before anything is allocated: what every reader
of robocli (``info``, ``dump --file``, ``plot``, ``export``, ``validate``, the replays,
``recover``) stands on.

A file says how long each of its records is and how large each chunk becomes once
decompressed; a damaged or hostile file says anything. Here a record may be no longer than
what remains of the file (or of its chunk), a chunk may declare no more than
:data:`MAX_CHUNK_BYTES` uncompressed and no more than its compressed size can yield
(:data:`MAX_RATIO`), and it is decompressed as a stream, piece by piece, never past what it
declared: memory follows what the file really holds, never what it claims. The records are
parsed by the ``mcap`` package's own record classes, over a view that refuses to read past
the record's end.

Two kinds of bad file, both :class:`BadRecording` (exit 2 at the CLI):

- :class:`TruncatedRecording`, a file that ends inside a record or without its footer (a
  recording that was killed, or whose disk filled up): everything up to the last complete
  record reads, :attr:`McapFile.truncated` says so, and ``robocli recover FILE`` rewrites it
  whole (:func:`truncated_hint`);
- anything else malformed (a record whose fields run past its end, text that is not UTF-8, a
  chunk that does not decompress to what it declares or whose CRC fails): the error names
  the record and its byte offset.
"""

from __future__ import annotations

import contextlib
import logging
import os
import struct
import zlib
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, Any

from robocli.closing import Closing
from robocli.errors import EXIT_USAGE, RobocliError

log = logging.getLogger("robocli.io.record")

__all__ = ["MAGIC", "MAX_CHUNK_BYTES", "MAX_RATIO", "MAX_RECORD_BYTES", "TRUNCATED_ATTR",
           "BadRecording", "McapFile", "TruncatedRecording", "decompress", "truncated_hint",
           "warn_truncated"]  # fmt: skip

MAGIC = b"\x89MCAP0\r\n"
#: The most a chunk may declare uncompressed (bytes): robocli's recorder closes chunks at
#: 4 MiB (one large message, a camera image, may make one a few MiB larger); other writers
#: use 1-8 MiB, and put a message larger than that (a 4K image: 25 MB) in a chunk of its own.
MAX_CHUNK_BYTES = 64 << 20
#: The most any other record may be (bytes): an attachment, a large schema.
MAX_RECORD_BYTES = 1 << 30
#: The most one compressed byte can become: zstd's run-length blocks (4 bytes for 128 KiB),
#: lz4's 255-byte match extensions; an uncompressed chunk is as long as it says.
MAX_RATIO = {"zstd": 32768, "lz4": 256, "": 1}
#: What a chunk's decompression hands over at a time (bytes).
_PIECE = 1 << 20
_HEAD = struct.Struct("<BQ")  # opcode, record length
_FOOTER = struct.Struct("<BQQQI")  # opcode, length, summary start, summary offset start, crc
_FOOTER_LEN = _FOOTER.size + len(MAGIC)
_NAMES = {0x01: "Header", 0x02: "Footer", 0x03: "Schema", 0x04: "Channel", 0x05: "Message",
          0x06: "Chunk", 0x07: "MessageIndex", 0x08: "ChunkIndex", 0x09: "Attachment",
          0x0A: "AttachmentIndex", 0x0B: "Statistics", 0x0C: "Metadata",
          0x0D: "MetadataIndex", 0x0E: "SummaryOffset", 0x0F: "DataEnd"}  # fmt: skip
#: The records a chunk may hold.
_IN_CHUNK = frozenset((0x03, 0x04, 0x05))


class BadRecording(RobocliError):
    """A recording that cannot be read as MCAP: not one, or damaged. Exit 2 (a bad file)."""

    exit_code = EXIT_USAGE


class TruncatedRecording(BadRecording):
    """A recording that ends before its footer (killed, or its disk filled): what is before
    the cut reads; ``robocli recover`` rewrites it whole."""


def truncated_hint(path: str | Path) -> str:
    """The sentence every reader says of a file cut short."""
    return f"{path} is truncated (a recording that was killed?): robocli recover {path}"


#: The attribute of the warning :func:`warn_truncated` logs (what the CLI prints as a note).
TRUNCATED_ATTR = "robocli_truncated"


def warn_truncated(path: str | Path) -> None:
    """Log (warning) that the file at ``path`` was read up to where it is cut, with
    :func:`truncated_hint`; the record carries ``path`` as :data:`TRUNCATED_ATTR`."""
    log.warning("%s", truncated_hint(path), extra={TRUNCATED_ATTR: str(path)})


class _TruncationNotes(logging.Handler):
    """Hands each file's :func:`warn_truncated` hint, once per file, to ``say``."""

    def __init__(self, say: Callable[[str], None]) -> None:
        super().__init__(logging.WARNING)
        self.say, self.seen = say, set[str]()

    def emit(self, record: logging.LogRecord) -> None:
        path = getattr(record, TRUNCATED_ATTR, None)
        if path is not None and path not in self.seen:
            self.seen.add(path)
            self.say(truncated_hint(path))


@contextlib.contextmanager
def truncation_notes(say: Callable[[str], None]) -> Iterator[None]:
    """While the block runs, a reader that meets a recording cut short tells ``say`` (once
    per file, :func:`truncated_hint`'s sentence) and goes on with what the file holds."""
    handler = _TruncationNotes(say)
    logger = logging.getLogger("robocli.io.record")
    logger.addHandler(handler)
    try:
        yield
    finally:
        logger.removeHandler(handler)


class _Malformed(Exception):
    """A field of one record that does not fit (turned into :class:`BadRecording`)."""


def _body_stream(body: bytes | memoryview) -> Any:
    """A ``mcap`` ReadDataStream over one record's body that raises rather than read past
    its end (the package's own stream returns short reads)."""
    from mcap.data_stream import ReadDataStream

    class Body(ReadDataStream):
        def __init__(self) -> None:
            self._count, self._crc, self._view = 0, None, memoryview(body)

        def read(self, length: int) -> bytes:
            end = self._count + length
            if length < 0 or end > len(self._view):
                raise _Malformed(f"a field of {length} bytes runs past the record's end")
            data = bytes(self._view[self._count : end])
            self._count = end
            return data

    return Body()


def _parse(opcode: int, body: bytes | memoryview) -> Any:
    """The ``mcap`` record of ``opcode`` read from its ``body``; None for an opcode MCAP does
    not define (skipped, as the specification says). Raises :class:`_Malformed`."""
    from mcap import records as r

    kinds: dict[int, Any] = {
        0x01: r.Header, 0x02: r.Footer, 0x03: r.Schema, 0x04: r.Channel, 0x06: r.Chunk,
        0x07: r.MessageIndex, 0x08: r.ChunkIndex, 0x09: r.Attachment,
        0x0A: r.AttachmentIndex, 0x0B: r.Statistics, 0x0C: r.Metadata,
        0x0D: r.MetadataIndex, 0x0E: r.SummaryOffset, 0x0F: r.DataEnd,
    }  # fmt: skip
    stream = _body_stream(body)
    try:
        if opcode == 0x05:
            return r.Message.read(stream, len(body))
        kind = kinds.get(opcode)
        return kind.read(stream) if kind is not None else None
    except UnicodeDecodeError:
        raise _Malformed("text that is not UTF-8") from None
    except struct.error as exc:  # pragma: no cover - every read is exact: struct gets its size
        raise _Malformed(str(exc)) from None


def decompress(chunk: Any) -> bytes | bytearray:
    """The records of ``chunk`` (an ``mcap`` Chunk), decompressed as a stream and never past
    the size it declares, which is first checked against :data:`MAX_CHUNK_BYTES` and what
    its compressed size can yield. Raises :class:`_Malformed`."""
    kind, declared, data = chunk.compression, chunk.uncompressed_size, chunk.data
    if kind not in MAX_RATIO:
        raise _Malformed(f"compression {kind[:40]!r} is not one MCAP defines (zstd, lz4)")
    if declared > MAX_CHUNK_BYTES:
        raise _Malformed(f"it declares {declared} bytes uncompressed, over the "
                         f"{MAX_CHUNK_BYTES >> 20} MiB a chunk may hold")  # fmt: skip
    if declared > len(data) * MAX_RATIO[kind] + (4096 if kind else 0):
        raise _Malformed(f"it declares {declared} bytes uncompressed, more than its "
                         f"{len(data)} {kind} bytes can hold")  # fmt: skip
    out: bytes | bytearray = _inflate(kind, data, declared) if kind else data
    if len(out) != declared:
        raise _Malformed(
            f"it declares {declared} bytes uncompressed and inflates to "
            f"{'more' if len(out) > declared else len(out)}"
        )
    if chunk.uncompressed_crc and zlib.crc32(out) != chunk.uncompressed_crc:
        raise _Malformed("its CRC does not match its contents")
    return out


def _inflate(kind: str, data: bytes, declared: int) -> bytearray:
    """Decompress at most ``declared`` + 1 bytes of ``data``, :data:`_PIECE` at a time."""
    out = bytearray()
    try:
        if kind == "zstd":
            import zstandard

            reader = zstandard.ZstdDecompressor().stream_reader(data, read_across_frames=True)
            while len(out) <= declared:
                piece = reader.read(min(_PIECE, declared + 1 - len(out)))
                if not piece:
                    break
                out += piece
        else:
            import lz4.frame  # type: ignore[import-untyped]

            inflater = lz4.frame.LZ4FrameDecompressor()
            feed = data
            while len(out) <= declared and not inflater.eof:
                piece = inflater.decompress(feed, max_length=min(_PIECE, declared + 1 - len(out)))
                feed = b""
                if not piece:
                    break
                out += piece
    except ImportError as exc:
        raise BadRecording(f"reading {kind} chunks needs {exc.name}: pip install "
                           "'robocli-robots[record]'") from None  # fmt: skip
    except Exception as exc:
        raise _Malformed(f"it does not decompress ({kind}: {exc})") from None
    return out


def chunk_records(chunk: Any) -> Iterator[Any]:
    """The Schema, Channel and Message records of ``chunk``, each length checked against what
    remains of the chunk. Raises :class:`_Malformed`."""
    data = decompress(chunk)
    view = memoryview(data)
    pos, end = 0, len(data)
    while pos < end:
        if end - pos < _HEAD.size:
            raise _Malformed(f"it ends inside a record header, at its byte {pos}")
        opcode, length = _HEAD.unpack_from(data, pos)
        pos += _HEAD.size
        if length > end - pos:
            raise _Malformed(f"a record at its byte {pos - _HEAD.size} is {length} bytes long, "
                             f"past the chunk's end")  # fmt: skip
        if opcode == 0:
            raise _Malformed(f"a record at its byte {pos - _HEAD.size} has opcode 0")
        if opcode in _IN_CHUNK:
            yield _parse(opcode, view[pos : pos + length])
        pos += length


class McapFile(Closing):
    """One MCAP file open for reading (see the module docstring). ``with McapFile(path) as f:
    for record in f.records(): ...``. Raises :class:`BadRecording` for a file that is not
    MCAP and :class:`TruncatedRecording` for one cut before its first record ends."""

    def __init__(self, path: str | Path) -> None:
        self.path = str(path)
        try:
            import mcap  # noqa: F401 - the optional extra
        except ImportError:
            raise BadRecording("reading MCAP needs the mcap package: pip install "
                               "'robocli-robots[record]'") from None  # fmt: skip
        try:
            self._file: IO[bytes] = Path(path).open("rb")
            self.size = os.fstat(self._file.fileno()).st_size
        except OSError as exc:
            raise RobocliError(f"cannot read {path}: {exc.strerror or exc}") from None
        #: the file ends with a footer and the magic (it was closed)
        self.finished = False
        #: the data ended before the footer (set as :meth:`records` meets it)
        self.truncated = False
        #: bytes up to the end of the last complete record read
        self.readable_bytes = 0
        #: chunks read by :meth:`records`, and their compressions in the order met
        self.chunks = 0
        self.compressions: list[str] = []
        try:
            head = self.read_at(0, min(len(MAGIC), self.size))
            if head != MAGIC:
                self.close()
                if MAGIC.startswith(head):
                    raise TruncatedRecording(f"{path} is truncated before its first record "
                                             "(nothing to read or recover)")  # fmt: skip
                raise BadRecording(f"{path} is not an MCAP file (no MCAP magic at its start)")
            self.finished = self._footer() is not None
        except BaseException:
            self.close()
            raise

    # -------------------------------------------------------------- plumbing

    def close(self) -> None:
        self._file.close()

    def read_at(self, offset: int, length: int) -> bytes:
        """``length`` bytes at ``offset``; :class:`BadRecording` when they are not all in the
        file (checked before reading)."""
        if offset < 0 or length < 0 or offset + length > self.size:
            raise BadRecording(f"{self.path}: {length} bytes at byte {offset} are past the "
                               f"file's end ({self.size} bytes)")  # fmt: skip
        try:
            self._file.seek(offset)
            data = self._file.read(length)
        except OSError as exc:
            raise RobocliError(f"cannot read {self.path}: {exc.strerror or exc}") from None
        if len(data) != length:  # the file shrank while read
            raise TruncatedRecording(truncated_hint(self.path))
        return data

    def bad(self, opcode: int, offset: int, why: str) -> BadRecording:
        """The error of a malformed record."""
        name = _NAMES.get(opcode, f"opcode 0x{opcode:02x}")
        return BadRecording(f"{self.path}: the {name} record at byte {offset} is malformed: "
                            f"{why}")  # fmt: skip

    def _footer(self) -> Any:
        """The Footer record, or None when the file does not end with one and the magic."""
        if self.size < len(MAGIC) * 2 + _FOOTER.size:
            return None
        tail = self.read_at(self.size - _FOOTER_LEN, _FOOTER_LEN)
        if tail[_FOOTER.size :] != MAGIC:
            return None
        opcode, length = _HEAD.unpack_from(tail)
        if opcode != 0x02 or length != _FOOTER.size - _HEAD.size:
            return None
        return _parse(0x02, tail[_HEAD.size : _FOOTER.size])

    # -------------------------------------------------------------- the data section

    def spans(self) -> Iterator[tuple[int, int, int]]:
        """``(offset, opcode, length)`` of each record of the data section (up to and with
        its DataEnd; the summary follows), each whole in the file: where the file is cut,
        :attr:`truncated` is set and the iteration ends. A length past the data's end in a
        finished file raises :class:`BadRecording`."""
        pos = len(MAGIC)
        data_end = self.size - _FOOTER_LEN if self.finished else self.size
        self.readable_bytes = pos
        while True:
            if pos == data_end or data_end - pos < _HEAD.size:
                if not self.finished or pos != data_end:
                    self.truncated = True
                return
            opcode, length = _HEAD.unpack(self.read_at(pos, _HEAD.size))
            start = pos + _HEAD.size
            if opcode == 0 or length > data_end - start:
                if self.finished:
                    raise self.bad(opcode, pos, f"it is {length} bytes long, past the data's end"
                                   if opcode else "opcode 0 is no record")  # fmt: skip
                self.truncated = True  # cut inside this record (or a zero-filled tail)
                return
            if opcode == 0x02:  # a Footer before the end
                self.truncated = self.truncated or not self.finished
                return
            yield pos, opcode, length
            pos = start + length
            self.readable_bytes = pos
            if opcode == 0x0F:  # DataEnd: the summary follows
                self.truncated = self.truncated or not self.finished
                return

    def parse(self, offset: int, opcode: int, length: int, *, chunks: bool = True) -> list[Any]:
        """The record at ``offset`` (as :meth:`spans` gives it), or with ``chunks`` a
        chunk's records; [] for an opcode MCAP does not define. Raises
        :class:`BadRecording` when it is malformed."""
        if opcode not in _NAMES:
            return []
        limit = MAX_CHUNK_BYTES + 4096 if opcode == 0x06 else MAX_RECORD_BYTES
        if length > limit:
            raise self.bad(opcode, offset, f"it is {length} bytes long, over {limit >> 20} MiB")
        body = self.read_at(offset + _HEAD.size, length)
        try:
            record = _parse(opcode, body)
            if opcode != 0x06:
                return [record]
            inner = list(chunk_records(record)) if chunks else [record]
        except _Malformed as exc:
            raise self.bad(opcode, offset, str(exc)) from None
        self.chunks += 1
        if record.compression and record.compression not in self.compressions:
            self.compressions.append(record.compression)
        return inner

    def records(self, *, chunks: bool = True, skip: frozenset[int] = frozenset()
                ) -> Iterator[Any]:  # fmt: skip
        """The data section's records in file order (see :meth:`spans`): with ``chunks``
        each chunk's records in its place, else the Chunk records themselves. Opcodes in
        ``skip`` are stepped over without being parsed. A malformed record raises
        :class:`BadRecording`."""
        for offset, opcode, length in self.spans():
            if opcode not in skip:
                yield from self.parse(offset, opcode, length, chunks=chunks)

    def chunk_at(self, offset: int, length: int) -> list[Any]:
        """The records of the Chunk record at ``offset`` (``length`` bytes, as a ChunkIndex
        says)."""
        if length < _HEAD.size or length > MAX_CHUNK_BYTES + 4096:
            raise BadRecording(f"{self.path}: the summary gives a chunk of {length} bytes at "
                               f"byte {offset}")  # fmt: skip
        data = self.read_at(offset, length)
        opcode, body_len = _HEAD.unpack_from(data)
        if opcode != 0x06 or body_len != length - _HEAD.size:
            raise BadRecording(f"{self.path}: the summary points at byte {offset}, where no "
                               f"chunk of {length} bytes starts")  # fmt: skip
        try:
            return list(chunk_records(_parse(0x06, data[_HEAD.size :])))
        except _Malformed as exc:
            raise self.bad(0x06, offset, str(exc)) from None

    # -------------------------------------------------------------- the summary

    def summary(self) -> Any:
        """The summary section (an ``mcap`` Summary: schemas, channels, chunk indexes,
        statistics), or None when the file has none. Raises :class:`BadRecording` when it
        is malformed."""
        from mcap import records as r
        from mcap.summary import Summary

        footer = self._footer()
        if footer is None or footer.summary_start == 0:
            return None
        start, end = footer.summary_start, self.size - _FOOTER_LEN
        if not len(MAGIC) <= start <= end:
            raise BadRecording(f"{self.path}: the footer puts the summary at byte {start}, "
                               "outside the file")  # fmt: skip
        block = self.read_at(start, end - start)
        summary = Summary()
        pos = 0
        while pos < len(block):
            if len(block) - pos < _HEAD.size:
                raise self.bad(0, start + pos, "the summary ends inside a record header")
            opcode, length = _HEAD.unpack_from(block, pos)
            body_at = pos + _HEAD.size
            if length > len(block) - body_at:
                raise self.bad(opcode, start + pos, "it runs past the summary's end")
            try:
                record = _parse(opcode, block[body_at : body_at + length])
            except _Malformed as exc:
                raise self.bad(opcode, start + pos, str(exc)) from None
            pos = body_at + length
            if isinstance(record, r.Schema):
                summary.schemas[record.id] = record
            elif isinstance(record, r.Channel):
                summary.channels[record.id] = record
            elif isinstance(record, r.ChunkIndex):
                summary.chunk_indexes.append(record)
            elif isinstance(record, r.Statistics):
                summary.statistics = record
            elif isinstance(record, r.AttachmentIndex):
                summary.attachment_indexes.append(record)
            elif isinstance(record, r.MetadataIndex):
                summary.metadata_indexes.append(record)
        return summary

    def header(self) -> Any:
        """The Header record (the first of the file), or None."""
        from mcap.records import Header

        for record in self.records(chunks=False):
            return record if isinstance(record, Header) else None
        return None
