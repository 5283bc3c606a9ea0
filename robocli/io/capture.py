"""Captured byte streams: read them back frame by frame, in bounded memory, and record them.

Formats, by suffix:

* ``.jsonl``: one JSON object per chunk of bytes, in time order::

      {"event": "start", "unix_time": 1764033000.123456}
      {"t": 0.046518, "dir": "s2c", "hex": "fafb03000000"}
      {"t": 0.051002, "dir": "c2s", "port": "motion", "hex": "..."}

  ``t`` is seconds since the capture started, ``dir`` is ``c2s`` (host to robot) or ``s2c``
  (robot to host), ``hex`` the bytes as they arrived (any chunking; frames may span lines),
  ``port`` (optional) the link of a device with several (an arm's ``motion`` and ``state``
  ports: each framed apart, read back as direction ``tx:motion``). The ``start`` event
  (optional: older captures and the traces lack it) gives the Unix time of ``t`` 0
  (:attr:`CaptureStats.start_unix`). This is the format of the recorded traces in
  ``tests/data/arcos`` and of ``robocli dump pioneer|arm|hub --output FILE.jsonl``; other
  lines without ``hex`` are events and are skipped.
* ``.mcap``: a recording of ``robocli record`` (:mod:`robocli.io.record`): the frames of
  the raw channels of one link speaking the protocol asked for, in log-time order, ``t``
  in seconds since the recording's first message, whose log time is the ``start_unix``
  (needs ``robocli-robots[record]``);
* anything else: raw bytes of one direction (what a serial sniffer or ``cat`` saved).

Files are streamed in chunks of :data:`CHUNK` bytes, so a capture of any size is read in
constant memory; a JSON line longer than :data:`MAX_LINE` bytes, an undecodable line and
bytes that form no frame are counted in :class:`CaptureStats`. Reading gives up, with
:class:`NoFrameError`, after :data:`MAX_GAP` bytes without a frame: a device file
(``/dev/zero``, ``/dev/urandom``) or a pipe of noise never ends, and is no capture.
"""

from __future__ import annotations

import io
import json
import math
import os
import select
import stat
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO

from robocli.closing import Closing
from robocli.core import Framer
from robocli.errors import EXIT_USAGE, RobocliError

#: Bytes read from a file at a time.
CHUNK = 64 * 1024
#: Longest accepted line of a ``.jsonl`` capture (a longer one is dropped, read in pieces).
MAX_LINE = 1024 * 1024
#: Bytes of a capture read without a single frame after which reading gives up
#: (:class:`NoFrameError`). A frame of ARCOS is at most 258 bytes, of Simple Message 4100.
MAX_GAP = 16 * 1024 * 1024

#: direction names used in captures -> "tx" (host to robot) / "rx" (robot to host)
_DIRECTIONS = {"c2s": "tx", "client->server": "tx", "s2c": "rx", "server->client": "rx"}
_NAMES = {"tx": "c2s", "rx": "s2c"}
#: what a frame of each protocol is called in messages
_FRAME_NAMES = {
    "arcos": "ARCOS packet", "sm-le": "Simple Message frame",
    "sm-be": "Simple Message frame (big-endian)", "ros4mat": "ros4mat message",
}  # fmt: skip


#: Lines a deferred :class:`CaptureWriter` holds before its file is made.
MAX_HELD = 10_000


class CaptureFileError(RobocliError):
    """A capture file that cannot be opened (no such folder, no permission): the file the
    caller named is unusable, a usage error (exit 2)."""

    exit_code = EXIT_USAGE


class NoFrameError(RobocliError):
    """:data:`MAX_GAP` bytes of a capture without a frame: reading stopped there (exit 1)."""


@dataclass(frozen=True)
class CapturedFrame:
    """One frame of a capture."""

    t: float | None  #: seconds since the capture started, when the format has it
    #: "tx" host->robot, "rx" robot->host, "?" unknown (raw files); "tx:motion" with a port
    direction: str
    frame: bytes  #: one whole frame (sync/prefix included)


@dataclass
class CaptureStats:
    """What reading a capture found: bytes read, frames, and bytes that formed no frame
    (garbage, bad checksums, an unfinished last frame, undecodable JSON lines)."""

    bytes_read: int = 0
    frames: int = 0
    dropped_bytes: int = 0
    #: Unix time (s) of the capture's ``t`` 0, when it says (read before its first frame)
    start_unix: float | None = None


def read_capture(
    path: str | Path,
    protocol: str = "arcos",
    stats: CaptureStats | None = None,
    max_gap: int = MAX_GAP,
) -> Iterator[CapturedFrame]:
    """Frames of a capture file in order, streamed; each direction is framed separately, so
    garbage in one direction never hides the other's frames. ``stats`` (optional) is
    updated as the file is read. Raises :class:`CaptureFileError` when the file cannot be
    read, :class:`NoFrameError` after ``max_gap`` bytes of the file without a frame."""
    path = Path(path)
    stats = CaptureStats() if stats is None else stats
    try:
        if path.suffix == ".mcap":
            from robocli.io.record.reader import raw_frames

            for t, direction, frame in raw_frames(path, protocol, stats):
                yield CapturedFrame(t, direction, frame)
            return
        stream = _open(path)
    except OSError as exc:
        raise CaptureFileError(f"{path}: cannot read ({exc.strerror or exc})") from None
    gap = _Gap(path, protocol, stats, max_gap)
    try:
        with stream:
            if path.suffix == ".jsonl":
                yield from _read_jsonl(stream, protocol, stats, gap)
            else:
                yield from _read_raw(stream, protocol, stats, gap)
    except OSError as exc:
        raise CaptureFileError(f"{path}: cannot read ({exc.strerror or exc})") from None


#: How often a read from a pipe wakes to let a pending Ctrl-C through (s).
PIPE_WAKE = 0.2


class _WakingPipe(io.RawIOBase):
    """A pipe's (or terminal's) reading end whose reads wake every :data:`PIPE_WAKE` s.

    A signal that lands after Python checked for signals and before a blocking ``read()``
    began is only seen once ``read()`` returns: from a writer that keeps the pipe open and
    sends nothing, never. Ctrl-C was then lost (one ``dump --file FIFO`` in eight, on a
    loaded machine). Waiting in ``select()`` with a timeout bounds that to one wake-up."""

    def __init__(self, raw: io.FileIO) -> None:
        super().__init__()
        self._raw = raw

    def readable(self) -> bool:
        return True

    def fileno(self) -> int:
        return self._raw.fileno()

    def readinto(self, buffer: bytearray | memoryview) -> int | None:  # type: ignore[override]
        fd = self._raw.fileno()
        while not select.select([fd], [], [], PIPE_WAKE)[0]:
            pass  # back in Python: a pending signal raises here
        return self._raw.readinto(buffer)

    def close(self) -> None:
        try:
            self._raw.close()
        finally:
            super().close()


def _open(path: Path) -> IO[bytes]:
    """``path`` for reading; a pipe, socket or character device through :class:`_WakingPipe`."""
    raw = io.FileIO(path, "rb")
    try:
        mode = os.fstat(raw.fileno()).st_mode
    except OSError:
        raw.close()
        raise
    if stat.S_ISREG(mode) or stat.S_ISBLK(mode):
        return io.BufferedReader(raw)
    return io.BufferedReader(_WakingPipe(raw))


class _Gap:
    """Gives up reading after ``limit`` bytes of the file without a frame."""

    def __init__(self, path: Path, protocol: str, stats: CaptureStats, limit: int) -> None:
        self.path, self.protocol, self.stats, self.limit = path, protocol, stats, limit
        self.since = 0  #: ``stats.bytes_read`` after the last frame

    def framed(self) -> None:
        self.since = self.stats.bytes_read

    def check(self) -> None:
        if self.stats.bytes_read - self.since > self.limit:
            what = _FRAME_NAMES.get(self.protocol, f"{self.protocol} frame")
            raise NoFrameError(
                f"{self.path}: no {what} in {_size(self.limit)}, up to byte "
                f"{self.stats.bytes_read}: not a capture of this protocol; stopped reading"
            )


def _size(n: int) -> str:
    return f"{n / 2**20:g} MiB" if n >= 2**20 else f"{n} bytes"


def _read_raw(stream: IO[bytes], protocol: str, stats: CaptureStats,
              gap: _Gap) -> Iterator[CapturedFrame]:  # fmt: skip
    framer = Framer(protocol)
    try:
        while chunk := stream.read(CHUNK):
            stats.bytes_read += len(chunk)
            for frame in framer.feed(chunk):
                stats.frames += 1
                gap.framed()
                yield CapturedFrame(None, "?", frame)
            gap.check()
    finally:
        stats.dropped_bytes += framer.stats.dropped_bytes + framer.pending


def _read_jsonl(stream: IO[bytes], protocol: str, stats: CaptureStats,
                gap: _Gap) -> Iterator[CapturedFrame]:  # fmt: skip
    framers: dict[str, Framer] = {}
    try:
        while line := stream.readline(MAX_LINE):
            stats.bytes_read += len(line)
            if not line.endswith(b"\n") and len(line) == MAX_LINE:
                stats.dropped_bytes += len(line)
                _skip_line(stream, stats, gap)
                gap.check()
                continue
            record = _record(line, stats)
            if record is None:
                stats.dropped_bytes += len(line.strip())
                gap.check()
                continue
            t, direction, data = record
            framer = framers.setdefault(direction, Framer(protocol))
            for frame in framer.feed(data):
                stats.frames += 1
                gap.framed()
                yield CapturedFrame(t, direction, frame)
            gap.check()
    finally:
        for framer in framers.values():
            stats.dropped_bytes += framer.stats.dropped_bytes + framer.pending


def _record(line: bytes, stats: CaptureStats) -> tuple[float | None, str, bytes] | None:
    """(t, direction, bytes) of one capture line; None for a line that is not a record
    (an event line without bytes gives empty bytes; a ``start`` event sets
    ``stats.start_unix``)."""
    if not line.strip():
        return None
    try:
        record = json.loads(line)
        data = bytes.fromhex(record.get("hex", ""))
        t = record.get("t")
        t = float(t) if t is not None else None
        if record.get("event") == "start" and stats.start_unix is None:
            start = float(record["unix_time"])
            stats.start_unix = start if math.isfinite(start) else None
    except (ValueError, TypeError, AttributeError, KeyError, RecursionError):  # not JSON, not
        return None  # an object, bad hex or t, or nested too deeply
    direction = _DIRECTIONS.get(str(record.get("dir")), "?")
    port = record.get("port")
    if isinstance(port, str) and port:
        direction = f"{direction}:{port[:32]}"
    return t, direction, data


def _skip_line(stream: IO[bytes], stats: CaptureStats, gap: _Gap) -> None:
    """Read to the end of an overlong line, counting it as dropped (a line that never ends,
    as ``/dev/zero``'s, ends at the gap limit)."""
    while piece := stream.readline(MAX_LINE):
        stats.bytes_read += len(piece)
        stats.dropped_bytes += len(piece)
        if piece.endswith(b"\n"):
            break
        gap.check()


class CaptureWriter(Closing):
    """Record a session in the ``.jsonl`` capture format (see the module docstring), one
    line per packet, flushed as it goes so that an interrupted session keeps what it saw.
    Thread-safe: packets sent and received in different threads never interleave.

    The path is checked at once (:func:`~robocli.output.check_output`: an existing file
    is refused unless ``overwrite``, a symbolic link always). With ``deferred``, the file is
    made by :meth:`open` (a command calls it once its session is connected), and the lines
    before it (a handshake's, at most :data:`MAX_HELD`) wait in memory: a session that
    fails to connect writes nothing."""

    def __init__(self, path: str | Path, overwrite: bool = False, *,
                 deferred: bool = False) -> None:  # fmt: skip
        from robocli.output import check_output

        self.path = check_output(path, overwrite)
        self._overwrite = overwrite
        self._file: IO[str] | None = None
        self._held: list[str] = []
        self._closed = False
        self._lock = threading.Lock()
        self.records = 0
        self.start_unix: float | None = None
        if not deferred:
            self.open()

    def open(self) -> None:
        """Make the file and write the lines held so far. Idempotent."""
        from robocli.output import create_output

        with self._lock:
            if self._file is not None or self._closed:
                return
            self._file = create_output(self.path, self._overwrite, text=True)
            held, self._held = self._held, []
            for line in held:
                self._file.write(line)
            self._file.flush()

    def _emit(self, line: str) -> bool:
        """Write one line (lock held); False once closed or when none more can be held."""
        if self._closed:
            return False
        if self._file is None:
            if len(self._held) >= MAX_HELD:
                return False
            self._held.append(line)
            return True
        self._file.write(line)
        self._file.flush()
        return True

    def begin(self, start_unix: float) -> None:
        """Say when ``t`` 0 was (Unix time, s): a ``start`` event line, once, before the
        records (a capture without it stays readable, without a time base)."""
        with self._lock:
            if self.start_unix is not None or self._closed:
                return
            self.start_unix = start_unix
            self._emit(json.dumps({"event": "start", "unix_time": round(start_unix, 6)}) + "\n")

    def write(self, t: float, direction: str, data: bytes, port: str | None = None) -> None:
        """Append ``data`` sent ("tx") or received ("rx") at ``t`` s since the start, on
        ``port`` (an arm's ``motion`` or ``state``: kept, so that replays tell them apart)."""
        record: dict[str, object] = {"t": round(t, 6), "dir": _NAMES.get(direction, "?")}
        if port:
            record["port"] = port
        record["hex"] = data.hex()
        line = json.dumps(record)
        with self._lock:
            if self._emit(line + "\n"):
                self.records += 1

    def close(self) -> None:
        """Close the file (never made: nothing is written); idempotent."""
        with self._lock:
            self._closed = True
            if self._file is not None:
                self._file.close()
