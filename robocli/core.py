"""Typed wrapper of the C core (``robocli._core``, built by cffi from ``csrc/``).

This is the only module that imports the compiled extension. It offers:

* :func:`arcos_checksum` and :class:`Framer` -- find frames of ARCOS, Simple Message
  (little/big-endian length prefix), ros4mat and SCIP 2.0 in any chunking of a byte stream,
  resynchronising one byte at a time after garbage and counting what was dropped;
* :class:`Ring` -- one writer, many readers ring of timestamped fixed-size records, each
  reader with its own cursor and limit;
* :func:`align_nearest` / :func:`align_linear` -- map sorted sample times of K streams onto
  one sorted reference timeline;
* :class:`PingPong` / :func:`pingpong_floor` -- the machine's loopback TCP round-trip floor,
  measured in C, each end optionally pinned to a CPU;
* :class:`Responder` -- a minimal ARCOS server in C answering frames from a canned table.

The C calls release the GIL. :class:`Framer` objects are not thread-safe (use one per
stream); :class:`Ring` is thread-safe (the C ring locks itself). NumPy is imported only by the
ring, alignment and floor functions, so a client that only frames bytes does not load it.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Union

from robocli._core import ffi, lib
from robocli.errors import TransportError

if TYPE_CHECKING:  # NumPy is imported by the functions that need it: framing does not
    import numpy as np
    import numpy.typing as npt

__all__ = [
    "PROTOCOLS",
    "Framer",
    "FramerStats",
    "Ring",
    "align_linear",
    "align_nearest",
    "arcos_checksum",
    "pin_supported",
    "pingpong_floor",
    "PingPong",
    "Responder",
    "ResponderStats",
]

PROTOCOLS = ("arcos", "sm-le", "sm-be", "ros4mat", "scip2")

_PROTO_IDS = {
    "arcos": lib.RC_PROTO_ARCOS,
    "sm-le": lib.RC_PROTO_SM_LE,
    "sm-be": lib.RC_PROTO_SM_BE,
    "ros4mat": lib.RC_PROTO_ROS4MAT,
    "scip2": lib.RC_PROTO_SCIP2,
}

Buffer = Union[bytes, bytearray, memoryview]  # noqa: UP007 (a runtime alias on 3.10)


def _view(data: Any) -> memoryview:
    """A memoryview of any buffer-protocol object (bytes, arrays)."""
    return memoryview(data)


def _bytes_view(data: Buffer | npt.NDArray[Any]) -> Any:
    """A cffi ``unsigned char[]`` view of a bytes-like object or array (no copy when it is
    contiguous; a non-contiguous one is copied)."""
    if not isinstance(data, bytes | bytearray):
        view = _view(data)
        if not view.c_contiguous:
            data = view.tobytes()
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
    27 + 16 MiB, SCIP 65536). Bytes that cannot start a valid frame are dropped one at a time
    (SCIP: line by line, :mod:`robocli.protocols.scip2.framing`) and counted in :attr:`stats`.
    Not thread-safe: use one framer per stream.
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
        f = self._f
        if len(data):
            # bytes go to C as they are (cffi passes their buffer); other buffers get a view
            buf = data if type(data) is bytes else _bytes_view(data)
            if lib.rc_framer_feed(f, buf, len(buf)) != 0:
                raise MemoryError("framer buffer could not grow")
        # the loop of frames() inlined: this runs once per read on every link
        out: list[bytes] = []
        fp, lp, nxt, buffer = self._frame, self._len, lib.rc_framer_next, ffi.buffer
        while nxt(f, fp, lp):
            out.append(buffer(fp[0], lp[0])[:])
        return out

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
    counted in :meth:`lost`. A new reader sees only records pushed after it was added.

    Thread-safe: one thread may push while many read. The C ring serialises its calls with
    its own mutex, taken for the C work only; no Python lock is held across the C calls
    (each releases and retakes the GIL), so readers never queue behind a thread that is
    waiting for the GIL. Adding and removing readers also take a Python lock, to keep the
    set of known reader ids in step with the C ring.
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
        return int(lib.rc_ring_pushed(self._r))

    def push(self, t: float, record: Buffer | npt.NDArray[Any]) -> None:
        """Append one record (exactly ``record_size`` bytes) stamped ``t`` seconds."""
        nbytes = _view(record).nbytes
        if nbytes != self._record_size:
            raise ValueError(f"record has {nbytes} bytes, expected {self._record_size}")
        lib.rc_ring_push(self._r, float(t), _bytes_view(record))

    def push_many(self, t: npt.ArrayLike, records: Buffer | npt.NDArray[Any]) -> None:
        """Append n records: ``t`` shape (n,), ``records`` n * record_size bytes.

        ``records`` is typically a uint8 array of shape (n, record_size), or any contiguous
        array (e.g. a structured array of n records) holding n * record_size bytes.
        """
        import numpy as np

        tt = np.ascontiguousarray(t, dtype=np.float64)
        if tt.ndim != 1:
            raise ValueError("t must be one-dimensional")
        n = tt.shape[0]
        rec = np.ascontiguousarray(records) if isinstance(records, np.ndarray) else records
        nbytes = _view(rec).nbytes
        if nbytes != n * self._record_size:
            raise ValueError(f"records hold {nbytes} bytes, expected {n} x {self._record_size}")
        if n == 0:
            return
        tbuf = ffi.from_buffer("double[]", tt)
        lib.rc_ring_push_many(self._r, tbuf, _bytes_view(rec), n)

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
        self._check(reader)
        return int(lib.rc_ring_available(self._r, reader))

    def lost(self, reader: int) -> int:
        """Records dropped for ``reader`` because it fell more than its limit behind."""
        self._check(reader)
        return int(lib.rc_ring_lost(self._r, reader))

    def read(
        self, reader: int, max_records: int | None = None
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.uint8]]:
        """Take up to ``max_records`` unread records, oldest first.

        Returns ``(t, records)``: float64 shape (n,) and uint8 shape (n, record_size), freshly
        allocated (one copy out of the ring). Records pushed while it runs are left for the
        next read.
        """
        import numpy as np

        if max_records is not None and max_records < 0:
            raise ValueError("max_records must be >= 0")
        self._check(reader)
        r = self._r
        n = int(lib.rc_ring_available(r, reader))
        if max_records is not None:
            n = min(n, max_records)
        t = np.empty(n, dtype=np.float64)
        rec = np.empty((n, self._record_size), dtype=np.uint8)
        if n:
            tbuf = ffi.from_buffer("double[]", t)
            rbuf = ffi.from_buffer("unsigned char[]", rec)
            got = int(lib.rc_ring_read(r, reader, tbuf, rbuf, n))
            if got != n:  # the reader was removed meanwhile (the C ring's unread only grows)
                t, rec = t[:got], rec[:got]
        return t, rec


# ---------------------------------------------------------------------------- alignment


def _times(a: npt.ArrayLike, what: str) -> npt.NDArray[np.float64]:
    import numpy as np

    arr = np.ascontiguousarray(a, dtype=np.float64)
    if arr.ndim != 1:
        raise ValueError(f"{what} must be one-dimensional")
    return arr


def _streams(
    streams: Sequence[npt.ArrayLike] | npt.NDArray[Any],
) -> tuple[list[npt.NDArray[np.float64]], bool]:
    """The list of streams, and whether a single 1-D stream was given."""
    import numpy as np

    if isinstance(streams, np.ndarray):
        if streams.ndim == 1:
            return [_times(streams, "stream")], True
        if streams.ndim == 2:
            return [_times(row, "stream") for row in streams], False
        raise ValueError("streams must be a 1-D array, a 2-D array or a sequence of 1-D arrays")
    return [_times(s, "stream") for s in streams], False


def _long_out(shape: tuple[int, ...]) -> npt.NDArray[Any]:
    import numpy as np

    # C ``long`` is int64 on LP64 (Linux, macOS) but int32 on Windows: index outputs are
    # written as C long and returned as int64.
    return np.empty(shape, dtype=np.dtype("l"))


def _as_int64(a: npt.NDArray[Any]) -> npt.NDArray[np.int64]:
    import numpy as np

    return a if a.dtype == np.dtype(np.int64) else a.astype(np.int64)


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
    import numpy as np

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


def pin_supported() -> bool:
    """Whether threads can be pinned to a CPU here (Linux); elsewhere every ``cpu`` argument
    below must be None."""
    return bool(lib.rc_pin_supported())


def _cpu_arg(cpu: int | None) -> int:
    if cpu is None:
        return -1
    if cpu < 0:
        raise ValueError("cpu must be >= 0 (or None: not pinned)")
    if not pin_supported():
        raise ValueError("this platform cannot pin threads to a CPU; pass cpu=None")
    return cpu


class PingPong:
    """The machine's floor for request/acknowledge round trips: ``msg_size``-byte ping-pongs
    over one loopback TCP connection (TCP_NODELAY) between a C echo thread, pinned to
    ``echo_cpu``, and the thread that calls :meth:`run`, pinned to ``cpu`` for the call.

    The connection and the echo thread persist between calls, so a long measurement can run
    in short chunks and stay interruptible. Use as a context manager, or call :meth:`close`.
    """

    def __init__(self, msg_size: int = 16, echo_cpu: int | None = None) -> None:
        if not 0 < msg_size <= 65536:
            raise ValueError("msg_size must be 1..65536")
        ptr = lib.rc_pingpong_new(msg_size, _cpu_arg(echo_cpu))
        if ptr == ffi.NULL:
            raise TransportError("loopback ping-pong could not start (sockets or threads)")
        self._p: Any = ffi.gc(ptr, lib.rc_pingpong_free)
        self.msg_size = msg_size
        self.echo_cpu = echo_cpu

    def run(self, n: int, cpu: int | None = None) -> npt.NDArray[np.float64]:
        """``n`` round trips (seconds each) from this thread, pinned to ``cpu`` for the call
        (the previous affinity is restored). Releases the GIL while it runs."""
        import numpy as np

        if n <= 0:
            raise ValueError("n must be positive")
        if self._p is None:
            raise TransportError("ping-pong is closed")
        out = np.empty(n, dtype=np.float64)
        rc = lib.rc_pingpong_run(self._p, n, _cpu_arg(cpu), ffi.from_buffer("double[]", out))
        if rc == -2:
            raise ValueError(f"cannot pin to CPU {cpu} (echo CPU {self.echo_cpu})")
        if rc != 0:
            raise TransportError("loopback ping-pong failed")
        return out

    def close(self) -> None:
        """End the echo thread and close the sockets (bounded: the echo sees end of stream)."""
        if self._p is not None:
            ffi.release(self._p)  # runs rc_pingpong_free now
            self._p = None

    def __enter__(self) -> PingPong:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def pingpong_floor(
    n: int = 1000, msg_size: int = 16, cpu: int | None = None, echo_cpu: int | None = None
) -> npt.NDArray[np.float64]:
    """Round-trip times (seconds) of ``n`` ping-pongs of :class:`PingPong` (ends pinned to
    ``cpu`` and ``echo_cpu``, or left to the scheduler). Raises
    :class:`~robocli.errors.TransportError` if sockets fail or the platform has no POSIX
    threads."""
    if n <= 0 or msg_size <= 0:
        raise ValueError("n and msg_size must be positive")
    with PingPong(msg_size, echo_cpu) as pp:
        return pp.run(n, cpu)


@dataclass(frozen=True)
class ResponderStats:
    """Counters of a :class:`Responder` since it started."""

    connections: int
    frames: int
    replies: int
    pin_failed: bool


class Responder:
    """A minimal ARCOS responder in C on 127.0.0.1: for every complete ARCOS frame whose
    payload (type byte + data) is a key of ``table`` it writes that key's reply bytes
    (already framed); other frames get no reply. One client at a time, in a C thread pinned
    to ``cpu`` (None: not pinned). It isolates a client's own cost in a round trip.

    At most 256 entries; keys 1..4096 bytes, replies 0..4096 bytes.
    """

    def __init__(self, table: dict[bytes, bytes], cpu: int | None = None) -> None:
        if len(table) > 256:
            raise ValueError("at most 256 table entries")
        for key, reply in table.items():
            if not 0 < len(key) <= 4096 or len(reply) > 4096:
                raise ValueError("keys must be 1..4096 bytes, replies at most 4096 bytes")
        keys, replies = list(table), list(table.values())
        ptr = lib.rc_responder_new(
            b"".join(keys),
            ffi.new("size_t[]", [len(k) for k in keys] or [0]),
            b"".join(replies),
            ffi.new("size_t[]", [len(r) for r in replies] or [0]),
            len(keys),
        )
        if ptr == ffi.NULL:
            raise MemoryError("cannot allocate the responder table")
        self._r: Any = ffi.gc(ptr, lib.rc_responder_free)
        port = int(lib.rc_responder_start(self._r, _cpu_arg(cpu)))
        if port <= 0:
            raise TransportError("ARCOS responder could not listen on loopback")
        self.port = port
        self.cpu = cpu
        self._stats = ffi.new("rc_responder_stats *")
        self._final = ResponderStats(0, 0, 0, False)

    @property
    def url(self) -> str:
        """``tcp://127.0.0.1:PORT`` of the listening socket."""
        return f"tcp://127.0.0.1:{self.port}"

    @property
    def stats(self) -> ResponderStats:
        """The counters (after :meth:`close`: their final values)."""
        if self._r is None:
            return self._final
        lib.rc_responder_get_stats(self._r, self._stats)
        s = self._stats
        return ResponderStats(int(s.connections), int(s.frames), int(s.replies), bool(s.pin_failed))

    def close(self) -> None:
        """Stop the thread (within ~0.1 s; ~1 s if the peer stopped reading) and close."""
        if self._r is not None:
            lib.rc_responder_stop(self._r)
            self._final = self.stats
            ffi.release(self._r)  # rc_responder_free
            self._r = None

    def __enter__(self) -> Responder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
