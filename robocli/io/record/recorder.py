"""The MCAP recorder: listeners on the devices feed a bounded queue, one thread writes.

>>> with Recorder("run.mcap") as rec:                      # doctest: +SKIP
...     rec.add(robot)                                      # a Pioneer, an Arm, a Hub
...     rec.add(hub, sensors=("imu", "adc"))

**Listeners never wait.** What a device's thread hands over (a frame sent or received, a
laser scan, a joint sample) is appended to a queue under a short lock, and that is all: no
decoding, no encoding, no disk. A queue past :attr:`Recorder.max_queue` items or
:attr:`Recorder.max_queue_bytes` bytes (a stalled disk) drops what comes, counted in
:attr:`RecorderStats.dropped`: memory stays bounded and the robot's threads never block.
A listener cannot raise into the device (the devices isolate their listeners anyway).

**One writer thread** takes the queue in batches, decodes what it holds into channels
(:mod:`robocli.io.record.sources`), encodes JSON and adds the messages to the MCAP writer.
Chunks are compressed (zstd by default, lz4, or none) and closed every ``chunk_seconds``
(or once ``chunk_size`` bytes are held), then written through to the operating system: a
recording killed with SIGKILL loses at most about a second, and every complete chunk before
it reads back. :meth:`Recorder.close` writes the rest and the summary (statistics, chunk
and message indexes), so that readers seek instead of scanning.

**What it says it wrote.** :attr:`RecorderStats.messages` counts the messages of chunks
whose every byte reached the file (written with system calls, no buffer between: see
:class:`~robocli.io.record.fastwrite.WrittenBytes`), so that the count a program reports is
what a reader finds, after a crash or on a full disk too; ``added`` counts what was handed
to the writer, ``lost`` what a failed write kept out of the file.

**The file** is made only by :meth:`Recorder.begin` (at once, unless ``deferred``), never
through a symbolic link, and an existing one only with ``overwrite`` (see
:mod:`robocli.output`): a program connects its sources first, listening from their first
byte, so that a source that fails leaves every file as it was.

**Time.** Every message's log time is the host receive time in Unix-epoch nanoseconds: the
devices' monotonic receive times mapped with one offset taken when the recorder started (so
log times never jump with the wall clock). Its publish time is the source's own acquisition
time on the host clock where one is known (the hub's sample times through the client's
clock-offset estimate; the arm controller's ``robot_time`` through the smallest observed
receive-minus-robot-time), else the receive time.
"""

from __future__ import annotations

import contextlib
import io
import logging
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from robocli._version import __version__
from robocli.errors import InvalidArgument, RobocliError
from robocli.io.record.links import RAW_ENCODING, RAW_SCHEMA, SinkBase
from robocli.io.schemas import schema_bytes
from robocli.output import check_output, create_output

log = logging.getLogger("robocli.io.record")

__all__ = [
    "COMPRESSIONS",
    "RAW_ENCODING",
    "RAW_SCHEMA",
    "Recorder",
    "RecorderStats",
    "RecordingError",
]

COMPRESSIONS = ("zstd", "lz4", "none")

#: How long the writer sleeps when the queue is empty (s): listeners never wake it, so that
#: a listener's cost is an append.
_IDLE_S = 0.1
#: A backlog of this many bytes (a stalled disk or a starved process), once written, is
#: handed back to the operating system (glibc keeps freed memory otherwise: resident memory
#: would stay at the backlog's peak for the rest of the recording).
_TRIM_AFTER = 16 << 20


class RecordingError(RobocliError):
    """The recording could not be written (no ``mcap``, a full disk, a bad path)."""


@dataclass
class RecorderStats:
    """What a recorder did. ``messages``: messages in the file, in chunks that reached it
    whole (the operating system has them: a reader finds them after a crash of the
    program); ``added``: messages handed to the writer, the last chunk's included (what
    ``--count`` counts); ``lost``: added but not in the file, because writing failed (a full
    disk). Items dropped for a full queue, items whose decoding failed (their raw bytes are
    still recorded), and the longest queue seen (items)."""

    messages: int = 0
    added: int = 0
    lost: int = 0
    dropped: int = 0
    decode_errors: int = 0
    queue_peak: int = 0


def _mcap() -> Any:
    try:
        import mcap.writer
    except ImportError:
        raise RecordingError(
            "recording needs the mcap package: pip install 'robocli-robots[record]'"
        ) from None
    import mcap

    return mcap


class Recorder(SinkBase):
    """Record devices into one MCAP file on one timeline. See the module docstring.

    ``compression``: ``"zstd"`` (default), ``"lz4"`` or ``"none"``. ``chunk_seconds``: the
    longest a message waits before its chunk is written out (what a SIGKILL can lose).
    ``chunk_size``: bytes of messages after which a chunk is closed sooner.
    ``max_queue`` / ``max_queue_bytes``: what may wait for the writer before items are
    dropped (counted). ``path`` may also be an open binary stream with ``tell``: it is
    written and flushed, and left open. ``overwrite``: replace an existing file (else
    refused); ``deferred``: make the file at :meth:`begin`, not now. ``ros2``: write a ROS 2
    bag (:mod:`robocli.ros2.bag`: every channel's messages mapped to standard ROS 2 types in
    CDR; ``prefix_frames``: see :class:`~robocli.ros2.mapping.Mapper`). Raises
    :class:`~robocli.output.OutputError` when the file may not or cannot be created,
    :class:`RecordingError` without the ``mcap`` package.
    """

    def __init__(
        self,
        path: str | Path | IO[bytes],
        *,
        compression: str = "zstd",
        chunk_seconds: float = 1.0,
        chunk_size: int = 4 << 20,
        max_queue: int = 200_000,
        max_queue_bytes: int = 256 << 20,
        overwrite: bool = False,
        deferred: bool = False,
        ros2: bool = False,
        prefix_frames: bool = False,
    ) -> None:
        if compression not in COMPRESSIONS:
            raise InvalidArgument(f"compression is one of {', '.join(COMPRESSIONS)}, "
                                  f"not {compression!r}")  # fmt: skip
        if not 0 < chunk_seconds <= 3600 or chunk_size < 1024:
            raise InvalidArgument("chunk_seconds must be in (0, 3600] and chunk_size >= 1024")
        if max_queue < 1 or max_queue_bytes < 1:
            raise InvalidArgument("max_queue and max_queue_bytes must be >= 1")
        _mcap()
        if ros2:
            from robocli.ros2.types import typestore

            typestore()  # rosbags is there (or say so now, before any file or connection)
        self.ros2, self.prefix_frames = ros2, prefix_frames
        self._ros2: Any = None  # the Translator, once begun
        self._owned = isinstance(path, (str, Path))
        if isinstance(path, (str, Path)):  # refused now (exists, a link...), before connecting
            self.path = check_output(path, overwrite)
        else:
            self.path = Path(getattr(path, "name", "<stream>"))
        self._target, self._overwrite, self._chunk_size = path, overwrite, chunk_size
        self.compression = compression
        self.chunk_seconds = chunk_seconds
        self.max_queue = max_queue
        self.max_queue_bytes = max_queue_bytes
        self.stats = RecorderStats()
        #: the error that stopped the writer (a full disk), else None
        self.error: BaseException | None = None
        super().__init__()  # log times on an epoch fixed now, names, what to detach
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._sequence: dict[int, int] = {}
        self._mirrors: list[Any] = []
        self._mirrored: dict[int, list[tuple[Any, int]]] = {}
        self._lock = threading.Lock()
        self._queue: deque[tuple[Callable[..., None], tuple[Any, ...]]] = deque()
        self._queued_bytes = 0
        self._closing = False
        self._decode_logged: set[str] = set()
        #: raw links by name (see :meth:`listener`)
        self.links: dict[str, Any] = {}
        self._thread: threading.Thread | None = None
        if not deferred:
            self.begin()

    def begin(self) -> None:
        """Create the file and start writing (what listeners queued meanwhile included).
        ``Recorder(path)`` begins at once; ``Recorder(path, deferred=True)`` waits for this
        call, so that a program connects its sources (listening from their first byte) before
        the file is made: a source that fails leaves no file, and an existing one untouched.
        Raises :class:`~robocli.output.OutputError` when the file cannot be created (it
        exists, without ``overwrite``; a symbolic link; no such folder),
        :class:`RecordingError` when its header cannot be written. Idempotent."""
        if self._thread is not None:
            return
        if self._closed:
            raise RecordingError(f"{self.path}: the recorder is closed")
        mcap = _mcap()
        from mcap.writer import CompressionType, Writer

        from robocli.io.record.fastwrite import MessageAdder, WrittenBytes

        target = self._target
        if isinstance(target, (str, Path)):
            raw = create_output(target, self._overwrite, buffered=False)
            assert isinstance(raw, io.FileIO)
            self._file: Any = WrittenBytes(raw)
        else:
            self._file = io.BufferedWriter(target) if isinstance(target, io.RawIOBase) else target
        kind = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4,
                "none": CompressionType.NONE}[self.compression]  # fmt: skip
        try:
            self._writer = Writer(self._file, chunk_size=self._chunk_size, compression=kind)
            self._writer.start(profile="ros2" if self.ros2 else "",
                               library=f"robocli {__version__} (mcap "
                               f"{getattr(mcap, '__version__', '?')})")  # fmt: skip
            self._file.flush()
        except Exception as exc:
            if self._owned:
                with contextlib.suppress(OSError):
                    self._file.close()
            raise RecordingError(f"cannot write {self.path}: {exc}") from None
        if self.ros2:
            from robocli.ros2.bag import BagChannels, Translator

            self._ros2 = Translator(BagChannels(self._writer, prefix_frames=self.prefix_frames))
        self._adder = MessageAdder(self._writer, getattr(self._file, "tell", None))
        self._add_message = self._adder.add
        self._thread = threading.Thread(target=self._run, name="recorder", daemon=True)
        self._thread.start()

    # ------------------------------------------------------------------ sources

    def add(self, device: Any, name: str | None = None, **options: Any) -> str:
        """Record ``device`` (a :class:`~robocli.devices.pioneer.Pioneer`, an
        :class:`~robocli.devices.arm.Arm`, a :class:`~robocli.devices.hub.client.Hub`, a
        :class:`~robocli.devices.laser.Laser` or a :class:`~robocli.devices.create.Create`)
        under the topic prefix ``/name/`` (default ``pioneer``, ``arm``, ``hub``, ``laser``,
        ``create``, numbered when taken).
        Returns the name. Options by device: a hub's ``sensors`` are only named in its raw
        channels' metadata (the program, or :func:`~robocli.io.record.pull_hub`, pulls them);
        an arm's ``ports`` (``"both"``). Raises :class:`RecordingError` once closed."""
        from robocli.io.record import sources

        if self._closed:
            raise RecordingError(f"{self.path}: the recorder is closed")
        return sources.attach(self, device, name, **options)

    def listener(self, name: str, protocol: str, **metadata: str) -> Any:
        """A new raw-frame listener ``(direction, payload, t)`` for a link named ``name``
        (``name2``... when taken: its ``.name`` says), to hand to a device's
        ``connect(listeners=[...])`` so that the handshake is recorded too; a later
        ``add(device, listener.name)`` decodes on top of it. ``protocol``: the framer's name
        (``arcos``, ``sm-le``, ``sm-be``, ``ros4mat``, ``scip2``, ``create-oi``); ``metadata``
        goes into its channels."""
        from robocli.io.record import sources

        return sources.raw_link(self, name, protocol, **metadata)

    def mirror(self, sink: Any) -> None:
        """Also hand every message of the channels registered from now on to ``sink`` (its
        ``channel`` and ``write``, as a :class:`~robocli.io.record.links.Sink` has them), on
        the writer thread: a :class:`~robocli.io.record.live.LiveView` serves the recording
        live. Call it before adding devices. ``sink.write`` must not raise."""
        self._mirrors.append(sink)

    # ------------------------------------------------------------------ the queue

    def put(self, handler: Callable[..., None], args: tuple[Any, ...], size: int = 64) -> bool:
        """Queue ``handler(*args)`` for the writer thread (``size``: bytes it holds). Never
        blocks; returns False (and counts a drop) when the queue is full or closed."""
        with self._lock:
            queue = self._queue
            if (self._closing or len(queue) >= self.max_queue
                    or self._queued_bytes + size > self.max_queue_bytes):  # fmt: skip
                self.stats.dropped += 1
                return False
            queue.append((handler, args))
            self._queued_bytes += size
            if len(queue) > self.stats.queue_peak:
                self.stats.queue_peak = len(queue)
        return True

    def _take(self) -> tuple[deque[tuple[Callable[..., None], tuple[Any, ...]]], int]:
        """What is queued, and its bytes."""
        with self._lock:
            items, self._queue = self._queue, deque()
            size, self._queued_bytes = self._queued_bytes, 0
        return items, size

    # ------------------------------------------------------------------ writing (writer thread)

    def channel(self, topic: str, schema: str | None, *, encoding: str = "json",
                metadata: dict[str, str] | None = None) -> int:  # fmt: skip
        """The id of ``topic``'s channel, registered on first use (writer thread only)."""
        known = self._channels.get(topic)
        if known is not None:
            return known
        if self._ros2 is not None:  # the bag's channels come with the messages they map to
            cid: int = self._ros2.channel(topic, schema, metadata)
        else:
            sid = 0
            if schema is not None:
                sid = self._schemas.get(schema, 0)
                if not sid:
                    sid = self._writer.register_schema(schema, "jsonschema",
                                                       schema_bytes(schema))  # fmt: skip
                    self._schemas[schema] = sid
            cid = self._writer.register_channel(topic, encoding, sid, dict(metadata or {}))
        self._channels[topic] = cid
        if self._mirrors:
            self._mirrored[cid] = [
                (m, m.channel(topic, schema, encoding=encoding, metadata=metadata))
                for m in self._mirrors
            ]
        return cid

    def write(self, cid: int, data: bytes, log_ns: int, publish_ns: int | None = None) -> None:
        """Add one message to channel ``cid`` (writer thread only)."""
        if self._ros2 is not None:
            self.stats.added += self._ros2.write(cid, data, log_ns, publish_ns,
                                                 self._add_message)  # fmt: skip
        else:
            seq = self._sequence.get(cid, 0)
            self._sequence[cid] = seq + 1
            self._add_message(cid, log_ns, data, log_ns if publish_ns is None else publish_ns,
                              seq)  # fmt: skip
            self.stats.added += 1
        mirrored = self._mirrored.get(cid)
        if mirrored:
            for sink, mid in mirrored:
                sink.write(mid, data, log_ns, publish_ns)

    def decode_failed(self, where: str, exc: BaseException) -> None:
        """A handler could not decode what it was given: count it, log the first per source."""
        self.stats.decode_errors += 1
        if where not in self._decode_logged:
            self._decode_logged.add(where)
            log.warning("recorder: %s: %s (its raw bytes are kept; later failures are only "
                        "counted)", where, exc,
                        exc_info=not isinstance(exc, RobocliError))  # fmt: skip

    def _run(self) -> None:
        last_chunk = time.monotonic()
        backlog = False
        try:
            while True:
                items, size = self._take()
                if size >= _TRIM_AFTER:
                    backlog = True
                elif backlog and size < _TRIM_AFTER // 16:  # caught up: give the memory back
                    backlog = False
                    _trim()
                if not items:
                    if self._closing:
                        break
                    time.sleep(_IDLE_S)
                for handler, args in items:
                    try:
                        handler(*args)
                    except (OSError, MemoryError):
                        raise
                    except Exception as exc:
                        self.decode_failed(getattr(handler, "__qualname__", str(handler)), exc)
                now = time.monotonic()
                if now - last_chunk >= self.chunk_seconds:
                    last_chunk = now
                    self._flush()
            self._flush()  # the last chunk, counted as the others
            if self._ros2 is not None:
                self._ros2.bag.finish(self.path.name)
            self._writer.finish()  # type: ignore[no-untyped-call]
            self._file.flush()
        except BaseException as exc:
            self.error = exc
            self._count_written()
            with self._lock:
                self._closing = True  # listeners now drop, counted
                self._queue.clear()
            log.error("recorder: writing %s failed: %s", self.path, exc)

    def _flush(self) -> None:
        """Close the chunk in progress and hand everything to the operating system; its
        messages then count as written."""
        self._adder.flush()
        self._file.flush()
        self._confirm(None)

    def _count_written(self) -> None:
        """After a failed write: count what the file holds, the chunks whose last byte
        reached it (the one being written too when its own record is whole and only what
        follows it failed)."""
        from robocli.io.record.fastwrite import chunk_is_whole

        size = getattr(self._file, "written", -1)
        self._confirm(size)
        adder = self._adder
        if not adder.chunks and adder.in_chunk and size >= 0 and adder.chunk_start >= 0:
            try:
                whole = chunk_is_whole(self._file.fileno(), adder.chunk_start, size)
            except (OSError, ValueError):
                whole = False
            if whole:
                self.stats.messages += adder.in_chunk
                adder.in_chunk = 0
        self.stats.lost = self.stats.added - self.stats.messages

    def _confirm(self, size: int | None) -> None:
        """Count the messages of the chunks handed to the file whose end is within its first
        ``size`` bytes (None: all of them, flushed)."""
        chunks = self._adder.chunks
        while chunks and (size is None or 0 <= chunks[0][0] <= size):
            self.stats.messages += chunks.popleft()[1]

    def check(self) -> None:
        """Raise :class:`RecordingError` once writing failed (a full disk): recording goes
        on dropping everything, so a program should stop and :meth:`close`."""
        if self.error is not None:
            raise RecordingError(self._failure())

    def _failure(self) -> str:
        err = self.error
        why = err.strerror if isinstance(err, OSError) and err.strerror else str(err)
        return (f"writing {self.path} failed: {why}; what was written before reads back up "
                "to its last complete chunk")  # fmt: skip

    # ------------------------------------------------------------------ closing

    def close(self, timeout: float = 30.0) -> None:
        """Stop listening, write what is queued and the summary, close the file. Idempotent.
        Raises :class:`RecordingError` when writing failed (what was written before stays
        readable up to its last complete chunk). A recorder that never began (see
        :meth:`begin`) writes nothing: no file is made."""
        if not self._close_begins():
            return
        with self._lock:
            self._closing = True
            if self._thread is None:
                self._queue.clear()
                return
        self._thread.join(timeout)
        stuck = self._thread.is_alive()
        if not stuck and self._owned:
            try:
                self._file.close()
            except OSError as exc:
                self.error = self.error or exc
        if stuck:
            raise RecordingError(f"{self.path}: the writer did not finish within {timeout:g} s "
                                 "(a stalled disk?); complete chunks are readable")  # fmt: skip
        if self.error is not None:
            raise RecordingError(self._failure())

    def __repr__(self) -> str:
        return f"<Recorder {self.path} messages={self.stats.messages}>"

    @property
    def begun(self) -> bool:
        """True once the file was made (:meth:`begin`)."""
        return self._thread is not None


def _trim() -> None:
    """Return freed heap memory to the operating system (glibc's ``malloc_trim``; nothing
    elsewhere)."""
    import ctypes

    try:
        ctypes.CDLL(None).malloc_trim(0)
    except (OSError, AttributeError):  # not glibc
        pass
