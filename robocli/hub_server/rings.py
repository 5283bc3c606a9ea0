"""One ring per sensor, a cursor per subscriber (on the C multi-reader :class:`~robocli.core.Ring`).

A :class:`SensorRing` holds **one copy** of each sample of one sensor, whatever the number of
subscribers: each subscriber owns a :class:`Cursor` (its own read position and capacity).
When a subscriber falls more than its capacity behind, the oldest samples are dropped for it
alone and counted (:meth:`SensorRing.lost`). Memory is the ring (``capacity x itemsize``)
plus O(1) per cursor, never subscribers x capacity.

Records are NumPy structured arrays of the sensor's dtype (the wire record, plus padding for
variable-size blobs); :meth:`SensorRing.read` returns them as a structured view of the bytes
copied out of the ring. Wire-agnostic: no protocol is known here.

Pushes and reads take only the C ring's own lock (no second lock held across the GIL hand-offs
of a C call, which would make readers queue behind each other); cursor changes and
:meth:`SensorRing.reshape` take this module's lock.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from robocli.core import Ring

__all__ = ["Cursor", "SensorRing", "ring_capacity"]

MAX_RECORDS = 1 << 16  #: most records one ring may hold
DEFAULT_BUDGET = 64 << 20  #: bytes one ring may use by default


def ring_capacity(itemsize: int, wanted: int, budget: int = DEFAULT_BUDGET) -> int:
    """Records a ring of ``itemsize``-byte records holds: ``wanted`` bounded by ``budget`` bytes
    and :data:`MAX_RECORDS` (at least 2)."""
    return max(2, min(int(wanted), MAX_RECORDS, budget // max(1, itemsize)))


class _Store(NamedTuple):
    ring: Ring
    dtype: np.dtype[Any]
    generation: int


@dataclass
class Cursor:
    """One subscriber's position in a :class:`SensorRing`.

    ``slot`` is (reader id, ring generation), replaced as one value; ``limit``: records it may
    leave unread before the oldest are dropped (its capacity).
    """

    slot: tuple[int, int]
    limit: int
    lost_before: int = 0  #: lost in rings replaced by :meth:`SensorRing.reshape`
    #: lost before the samples its last read returned (:meth:`SensorRing.lost_seen`)
    lost_read: int = 0

    @property
    def reader(self) -> int:
        return self.slot[0]


class SensorRing:
    """The samples of one sensor: one writer (the sensor's driver), many cursors.

    Thread-safe. ``dtype`` is a NumPy structured dtype; ``capacity`` records are kept.
    """

    def __init__(self, name: str, dtype: np.dtype[Any], capacity: int) -> None:
        self.name = name
        self._lock = threading.Lock()
        self._cursors: list[Cursor] = []
        self._store = _Store(Ring(np.dtype(dtype).itemsize, capacity), np.dtype(dtype), 0)

    # ------------------------------------------------------------------ properties

    @property
    def dtype(self) -> np.dtype[Any]:
        return self._store.dtype

    @property
    def capacity(self) -> int:
        return self._store.ring.capacity

    @property
    def nbytes(self) -> int:
        """Bytes of sample storage (records and timestamps)."""
        store = self._store
        return store.ring.capacity * (store.dtype.itemsize + 8)

    @property
    def pushed(self) -> int:
        """Records pushed into the current ring."""
        return self._store.ring.pushed

    @property
    def cursors(self) -> int:
        """Cursors attached now."""
        with self._lock:
            return len(self._cursors)

    # ------------------------------------------------------------------ writer

    def push(self, t: npt.NDArray[np.float64], records: npt.NDArray[Any]) -> None:
        """Append ``len(t)`` records (a structured array of this ring's dtype)."""
        store = self._store
        if records.dtype != store.dtype:
            raise ValueError(f"{self.name}: records of {records.dtype}, ring holds {store.dtype}")
        store.ring.push_many(t, records)

    # ------------------------------------------------------------------ cursors

    def attach(self, limit: int) -> Cursor:
        """A new cursor seeing the samples pushed from now on, keeping at most ``limit``
        unread (bounded by the capacity)."""
        with self._lock:
            store = self._store
            limit = max(1, min(int(limit), store.ring.capacity))
            cursor = Cursor((store.ring.add_reader(limit), store.generation), limit)
            self._cursors.append(cursor)
        return cursor

    def detach(self, cursor: Cursor) -> None:
        """Forget ``cursor`` (idempotent)."""
        with self._lock:
            if cursor in self._cursors:
                self._cursors.remove(cursor)
                self._store.ring.remove_reader(cursor.reader)

    def set_limit(self, cursor: Cursor, limit: int) -> None:
        """Change a cursor's capacity (a new subscribe by the same client); its unread
        samples are discarded (not counted as lost: the client asked anew)."""
        with self._lock:
            store = self._store
            limit = max(1, min(int(limit), store.ring.capacity))
            if cursor not in self._cursors:
                return
            cursor.lost_before += store.ring.lost(cursor.reader)
            store.ring.remove_reader(cursor.reader)
            cursor.slot, cursor.limit = (store.ring.add_reader(limit), store.generation), limit

    def _current(self, cursor: Cursor) -> tuple[_Store, int] | None:
        """The store and reader id of ``cursor`` if it belongs to the current ring."""
        store = self._store
        reader, generation = cursor.slot
        return (store, reader) if generation == store.generation else None

    def available(self, cursor: Cursor) -> int:
        """Unread samples of ``cursor``."""
        with self._lock:
            return self._store.ring.available(cursor.reader)

    def lost(self, cursor: Cursor) -> int:
        """Samples dropped for ``cursor`` because it fell more than its limit behind."""
        with self._lock:
            if cursor not in self._cursors:
                return cursor.lost_before
            return cursor.lost_before + self._store.ring.lost(cursor.reader)

    def lost_seen(self, cursor: Cursor) -> int:
        """Samples dropped for ``cursor`` before the samples its last read returned: the
        ones its client can know of, from the gaps in what it received. :meth:`lost` also
        counts those dropped since, which its client sees at its next read, or never if it
        does not read again (a client gone, or one the count was taken before)."""
        return cursor.lost_read

    def read(self, cursor: Cursor) -> tuple[npt.NDArray[np.float64], npt.NDArray[Any]]:
        """Take every unread sample of ``cursor``: ``(t, records)``, oldest first (records is a
        structured array of :attr:`dtype`, one copy out of the ring). A cursor detached or
        moved by a concurrent :meth:`reshape` reads nothing this time."""
        current = self._current(cursor)
        if current is not None:
            store, reader = current
            try:
                t, raw = store.ring.read(reader)
            except ValueError:  # detached, or the ring replaced, meanwhile
                pass
            else:
                if len(t):  # just read: nothing can have overflowed since, unless a batch
                    # larger than its limit was pushed in between (then a few are counted early)
                    cursor.lost_read = cursor.lost_before + store.ring.lost(reader)
                return t, raw.view(store.dtype).reshape(len(t))
        dtype = self._store.dtype
        return np.empty(0, dtype=np.float64), np.empty(0, dtype=dtype)

    # ------------------------------------------------------------------ settings

    def reshape(self, dtype: np.dtype[Any], capacity: int) -> None:
        """Replace the storage for records of another layout (a camera's new resolution).

        Every cursor is kept with its limit (bounded by the new capacity); the unread samples
        of the old layout are discarded and counted as lost.
        """
        with self._lock:
            old = self._store
            dtype = np.dtype(dtype)
            new = _Store(Ring(dtype.itemsize, capacity), dtype, old.generation + 1)
            for c in self._cursors:
                c.lost_before += old.ring.lost(c.reader) + old.ring.available(c.reader)
                c.limit = min(c.limit, capacity)
                c.slot = (new.ring.add_reader(c.limit), new.generation)
            self._store = new
