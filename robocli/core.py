"""Typed wrapper of the C core (``robocli._core``, built by cffi from ``csrc/``).

This is the only module that imports the compiled extension. It offers:

* :func:`arcos_checksum` and :class:`Framer` -- find frames of ARCOS, Simple Message
  (little/big-endian length prefix) and ros4mat in any chunking of a byte stream,
  resynchronising one byte at a time after garbage and counting what was dropped;
* :class:`Ring` -- one writer, many readers ring of timestamped fixed-size records, each
  reader with its own cursor and limit;
* :func:`align_nearest` / :func:`align_linear` -- map sorted sample times of K streams onto
  one sorted reference timeline;
* :func:`pingpong_floor` -- the machine's loopback TCP round-trip floor, measured in C.

The C calls release the GIL. :class:`Framer` objects are not thread-safe (use one per
stream); :class:`Ring` serialises every call with a lock.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from robocli._core import ffi, lib
from robocli.errors import TransportError

__all__ = [
    "PROTOCOLS",
    "Framer",
    "FramerStats",
    "Ring",
    "align_linear",
    "align_nearest",
    "arcos_checksum",
    "pingpong_floor",
]

PROTOCOLS = ("arcos", "sm-le", "sm-be", "ros4mat")

_PROTO_IDS = {
    "arcos": lib.RC_PROTO_ARCOS,
    "sm-le": lib.RC_PROTO_SM_LE,
    "sm-be": lib.RC_PROTO_SM_BE,
    "ros4mat": lib.RC_PROTO_ROS4MAT,
}

# C ``long`` is int64 on LP64 (Linux, macOS) but int32 on Windows: index outputs are written
# as C long and returned as int64.
_C_LONG = np.dtype("l")
_INT64 = np.dtype(np.int64)

Buffer = bytes | bytearray | memoryview


def _bytes_view(data: Buffer | npt.NDArray[Any]) -> Any:
    """A cffi ``unsigned char[]`` view of a bytes-like object (no copy when contiguous)."""
    if isinstance(data, np.ndarray):
        data = np.ascontiguousarray(data)
    elif isinstance(data, memoryview) and not data.c_contiguous:
        data = data.tobytes()
    return ffi.from_buffer("unsigned char[]", data)


def arcos_checksum(data: Buffer) -> int:
    """ARCOS checksum (0..65535) of the type byte and data of a packet (bytes 3..N)."""
    buf = _bytes_view(data)
    return int(lib.rc_arcos_checksum(buf, len(buf)))


# ---------------------------------------------------------------------------- framers


@dataclass(frozen=True)
class FramerStats:
    """Counters of a :class:`Framer` since creation (not cleared by :meth:`Framer.reset`)."""

    frames: int
    dropped_bytes: int
    bad_checksums: int
    bad_lengths: int


class Framer:
    """Finds complete frames of one protocol in a byte stream.

    ``protocol`` is one of :data:`PROTOCOLS`. ``max_frame`` is the largest accepted frame in
    bytes, prefix/header included (default: ARCOS 258, Simple Message 4100, ros4mat
    27 + 16 MiB). Bytes that cannot start a valid frame are dropped one at a time and counted
    in :attr:`stats`. Not thread-safe: use one framer per stream.
    """

    def __init__(self, protocol: str, max_frame: int | None = None) -> None:
        if protocol not in _PROTO_IDS:
            raise ValueError(f"unknown protocol {protocol!r}; expected one of {PROTOCOLS}")
        if max_frame is not None and max_frame <= 0:
            raise ValueError("max_frame must be positive")
        ptr = lib.rc_framer_new(_PROTO_IDS[protocol], max_frame or 0)
        if ptr == ffi.NULL:
            raise ValueError(f"max_frame {max_frame} is too small for {protocol}")
        self._f = ffi.gc(ptr, lib.rc_framer_free)
        self._frame = ffi.new("const unsigned char **")
        self._len = ffi.new("size_t *")
        self._stats = ffi.new("rc_framer_stats *")
        self.protocol = protocol

    def feed(self, data: Buffer) -> list[bytes]:
        """Append ``data`` to the stream and return every frame now complete, in order."""
        if len(data):
            buf = _bytes_view(data)
            if lib.rc_framer_feed(self._f, buf, len(buf)) != 0:
                raise MemoryError("framer buffer could not grow")
        return list(self.frames())

    def frames(self) -> Iterator[bytes]:
        """Take the complete frames already buffered, without feeding."""
        f, fp, lp = self._f, self._frame, self._len
        nxt, buffer = lib.rc_framer_next, ffi.buffer
        while nxt(f, fp, lp):
            yield buffer(fp[0], lp[0])[:]

    @property
    def stats(self) -> FramerStats:
        lib.rc_framer_get_stats(self._f, self._stats)
        s = self._stats
        return FramerStats(
            int(s.frames), int(s.dropped_bytes), int(s.bad_checksums), int(s.bad_lengths)
        )

    @property
    def pending(self) -> int:
        """Bytes buffered but not yet framed (a partial frame, or bytes not yet judged)."""
        return int(lib.rc_framer_pending(self._f))

    def reset(self) -> None:
        """Forget the buffered bytes (after a reconnect); the counters are kept."""
        lib.rc_framer_reset(self._f)

    def count(self, data: Buffer, chunk: int = 0) -> int:
        """Feed ``data`` in ``chunk``-byte pieces (0: at once), drop the frames, count them.

        For benchmarks: no Python object is created per frame.
        """
        if chunk < 0:
            raise ValueError("chunk must be >= 0")
        buf = _bytes_view(data)
        return int(lib.rc_framer_count(self._f, buf, len(buf), chunk))


# ---------------------------------------------------------------------------- ring buffer


class Ring:
    """One writer, many readers ring of ``capacity`` records of ``record_size`` bytes.

    Every record carries a float64 timestamp. Each reader has its own cursor and limit: when
    more than ``limit`` records are unread, the oldest are dropped for that reader only and
    counted in :meth:`lost`. A new reader sees only records pushed after it was added. All
    methods are serialised by a lock, so one thread may push while others read.
    """

    def __init__(self, record_size: int, capacity: int) -> None:
        if record_size <= 0 or capacity <= 0:
            raise ValueError("record_size and capacity must be positive")
        ptr = lib.rc_ring_new(record_size, capacity)
        if ptr == ffi.NULL:
            raise MemoryError(f"cannot allocate a ring of {capacity} x {record_size} bytes")
        self._r = ffi.gc(ptr, lib.rc_ring_free)
        self._lock = threading.Lock()
        self._record_size = record_size
        self._capacity = capacity
        self._readers: set[int] = set()

    @property
    def record_size(self) -> int:
        return self._record_size

    @property
    def capacity(self) -> int:
        return self._capacity

    @property
    def pushed(self) -> int:
        """Records pushed since creation."""
        with self._lock:
            return int(lib.rc_ring_pushed(self._r))

    def push(self, t: float, record: Buffer | npt.NDArray[Any]) -> None:
        """Append one record (exactly ``record_size`` bytes) stamped ``t`` seconds."""
        nbytes = record.nbytes if isinstance(record, np.ndarray | memoryview) else len(record)
        if nbytes != self._record_size:
            raise ValueError(f"record has {nbytes} bytes, expected {self._record_size}")
        buf = _bytes_view(record)
        with self._lock:
            lib.rc_ring_push(self._r, float(t), buf)

    def push_many(self, t: npt.ArrayLike, records: Buffer | npt.NDArray[Any]) -> None:
        """Append n records: ``t`` shape (n,), ``records`` n * record_size bytes.

        ``records`` is typically a uint8 array of shape (n, record_size), or any contiguous
        array (e.g. a structured array of n records) holding n * record_size bytes.
        """
        tt = np.ascontiguousarray(t, dtype=np.float64)
        if tt.ndim != 1:
            raise ValueError("t must be one-dimensional")
        n = tt.shape[0]
        rec = np.ascontiguousarray(records) if isinstance(records, np.ndarray) else records
        nbytes = rec.nbytes if isinstance(rec, np.ndarray | memoryview) else len(rec)
        if nbytes != n * self._record_size:
            raise ValueError(f"records hold {nbytes} bytes, expected {n} x {self._record_size}")
        if n == 0:
            return
        tbuf = ffi.from_buffer("double[]", tt)
        rbuf = _bytes_view(rec)
        with self._lock:
            lib.rc_ring_push_many(self._r, tbuf, rbuf, n)

    def add_reader(self, limit: int | None = None) -> int:
        """New reader (id >= 0) seeing only later records; ``limit`` <= capacity (None: all)."""
        if limit is not None and limit <= 0:
            raise ValueError("limit must be positive (or None for the capacity)")
        with self._lock:
            rid = int(lib.rc_ring_add_reader(self._r, limit or 0))
            if rid < 0:
                raise MemoryError("cannot add a reader")
            self._readers.add(rid)
        return rid

    def _check(self, reader: int) -> None:
        if reader not in self._readers:
            raise ValueError(f"unknown reader {reader}")

    def remove_reader(self, reader: int) -> None:
        with self._lock:
            self._check(reader)
            lib.rc_ring_remove_reader(self._r, reader)
            self._readers.discard(reader)

    def available(self, reader: int) -> int:
        """Unread records of ``reader`` (never more than its limit)."""
        with self._lock:
            self._check(reader)
            return int(lib.rc_ring_available(self._r, reader))

    def lost(self, reader: int) -> int:
        """Records dropped for ``reader`` because it fell more than its limit behind."""
        with self._lock:
            self._check(reader)
            return int(lib.rc_ring_lost(self._r, reader))

    def read(
        self, reader: int, max_records: int | None = None
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.uint8]]:
        """Take up to ``max_records`` unread records, oldest first.

        Returns ``(t, records)``: float64 shape (n,) and uint8 shape (n, record_size), freshly
        allocated (one copy out of the ring).
        """
        if max_records is not None and max_records < 0:
            raise ValueError("max_records must be >= 0")
        with self._lock:
            self._check(reader)
            n = int(lib.rc_ring_available(self._r, reader))
            if max_records is not None:
                n = min(n, max_records)
            t = np.empty(n, dtype=np.float64)
            rec = np.empty((n, self._record_size), dtype=np.uint8)
            if n:
                got = int(
                    lib.rc_ring_read(
                        self._r,
                        reader,
                        ffi.from_buffer("double[]", t),
                        ffi.from_buffer("unsigned char[]", rec),
                        n,
                    )
                )
                if got != n:  # pragma: no cover - impossible under the lock
                    t, rec = t[:got], rec[:got]
        return t, rec


# ---------------------------------------------------------------------------- alignment


def _times(a: npt.ArrayLike, what: str) -> npt.NDArray[np.float64]:
    arr = np.ascontiguousarray(a, dtype=np.float64)
    if arr.ndim != 1:
        raise ValueError(f"{what} must be one-dimensional")
    return arr


def _streams(
    streams: Sequence[npt.ArrayLike] | npt.NDArray[Any],
) -> tuple[list[npt.NDArray[np.float64]], bool]:
    """The list of streams, and whether a single 1-D stream was given."""
    if isinstance(streams, np.ndarray):
        if streams.ndim == 1:
            return [_times(streams, "stream")], True
        if streams.ndim == 2:
            return [_times(row, "stream") for row in streams], False
        raise ValueError("streams must be a 1-D array, a 2-D array or a sequence of 1-D arrays")
    return [_times(s, "stream") for s in streams], False


def _long_out(shape: tuple[int, ...]) -> npt.NDArray[Any]:
    return np.empty(shape, dtype=_C_LONG)


def _as_int64(a: npt.NDArray[Any]) -> npt.NDArray[np.int64]:
    return a if a.dtype == _INT64 else a.astype(np.int64)


def align_nearest(
    streams: Sequence[npt.ArrayLike] | npt.NDArray[Any], ref: npt.ArrayLike, tol: float
) -> npt.NDArray[np.int64]:
    """Index of the sample nearest each reference time, per stream.

    ``streams``: K sorted sample-time arrays (a list, or a 2-D array of K rows), or one 1-D
    array. ``ref``: M sorted reference times on the same clock. Returns int64 of shape (K, M)
    (or (M,) for a single 1-D stream): the index of the nearest sample if it is within
    ``tol`` seconds, else -1; ties go to the earlier sample. Unsorted input gives
    meaningless (but memory-safe) results. O(n + M) per stream.
    """
    ss, single = _streams(streams)
    r = _times(ref, "ref")
    m = r.shape[0]
    out = _long_out((len(ss), m))
    rbuf = ffi.from_buffer("double[]", r)
    for k, s in enumerate(ss):
        lib.rc_align_nearest(
            ffi.from_buffer("double[]", s),
            s.shape[0],
            rbuf,
            m,
            float(tol),
            ffi.from_buffer("long[]", out[k]),
        )
    res = _as_int64(out)
    return res[0] if single else res


def align_linear(
    ts: Sequence[npt.ArrayLike] | npt.NDArray[Any], ref: npt.ArrayLike
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]:
    """Linear-interpolation indices and weights of each reference time, per stream.

    For each ``ref[i]`` inside ``[ts[0], ts[-1]]``: ``idx[i] = j`` with
    ``ts[j] <= ref[i] <= ts[j+1]`` and ``w[i]`` the weight of sample j+1, so the value is
    ``(1 - w) * x[j] + w * x[j+1]``. A reference equal to the last sample gives j = n-2,
    w = 1 (j = 0, w = 0 for a one-sample stream). Outside: idx -1, w 0. ``ts`` is one 1-D
    sorted array (results of shape (M,)) or K of them (results of shape (K, M)).
    """
    ss, single = _streams(ts)
    r = _times(ref, "ref")
    m = r.shape[0]
    idx = _long_out((len(ss), m))
    w = np.empty((len(ss), m), dtype=np.float64)
    rbuf = ffi.from_buffer("double[]", r)
    for k, s in enumerate(ss):
        lib.rc_align_linear(
            ffi.from_buffer("double[]", s),
            s.shape[0],
            rbuf,
            m,
            ffi.from_buffer("long[]", idx[k]),
            ffi.from_buffer("double[]", w[k]),
        )
    ires = _as_int64(idx)
    if single:
        return ires[0], w[0]
    return ires, w


# ---------------------------------------------------------------------------- latency floor


def pingpong_floor(n: int = 1000, msg_size: int = 16) -> npt.NDArray[np.float64]:
    """Round-trip times (seconds) of ``n`` ``msg_size``-byte ping-pongs between two C threads
    over loopback TCP with TCP_NODELAY: the floor any request/acknowledge exchange on this
    machine can reach. Raises :class:`~robocli.errors.TransportError` if sockets fail or the
    platform has no POSIX threads.
    """
    if n <= 0 or msg_size <= 0:
        raise ValueError("n and msg_size must be positive")
    out = np.empty(n, dtype=np.float64)
    if lib.rc_pingpong_tcp(n, msg_size, ffi.from_buffer("double[]", out)) != 0:
        raise TransportError("loopback ping-pong failed (sockets or threads unavailable)")
    return out
