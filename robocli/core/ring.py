"""One writer, many readers ring of timestamped fixed-size records (the C ring)."""

from __future__ import annotations

import threading
from typing import TYPE_CHECKING, Any

from robocli._core import ffi, lib
from robocli.core._buffers import Buffer, _bytes_view, _view

if TYPE_CHECKING:  # NumPy is imported by the methods that need it
    import numpy as np
    import numpy.typing as npt


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
