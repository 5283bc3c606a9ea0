"""One ring per sensor, a cursor per subscriber (on the C multi-reader :class:`~robocli.core.Ring`).

A :class:`SensorRing` holds **one copy** of each sample of one sensor, whatever the number of
subscribers: each subscriber owns a :class:`Cursor` (its own read position and capacity).
When a subscriber falls more than its capacity behind, the oldest samples are dropped for it
alone and counted (:attr:`Cursor.lost`). Memory is the ring (``capacity x itemsize``) plus
O(1) per cursor, never subscribers x capacity.

Records are NumPy structured arrays of the sensor's dtype (the wire record, plus padding for
variable-size blobs); :meth:`SensorRing.read` returns them as a structured view of the bytes
copied out of the ring. Wire-agnostic: no protocol is known here.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any

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


@dataclass
class Cursor:
    """One subscriber's position in a :class:`SensorRing`.

    ``limit``: records it may leave unread before the oldest are dropped (its capacity).
    """

    reader: int
    limit: int
    lost_before: int = 0  #: lost in rings replaced by :meth:`SensorRing.reshape`
    generation: int = 0


class SensorRing:
    """The samples of one sensor: one writer (the sensor's driver), many cursors.

    Thread-safe. ``dtype`` is a NumPy structured dtype; ``capacity`` records are kept.
    """

    def __init__(self, name: str, dtype: np.dtype[Any], capacity: int) -> None:
        self.name = name
        self._lock = threading.Lock()
        self._cursors: list[Cursor] = []
        self._generation = 0
        self._make(dtype, capacity)

    def _make(self, dtype: np.dtype[Any], capacity: int) -> None:
        self.dtype = np.dtype(dtype)
        self._ring = Ring(self.dtype.itemsize, capacity)

    # ------------------------------------------------------------------ properties

    @property
    def capacity(self) -> int:
        return self._ring.capacity

    @property
    def nbytes(self) -> int:
        """Bytes of sample storage (records and timestamps)."""
        return self._ring.capacity * (self.dtype.itemsize + 8)

    @property
    def pushed(self) -> int:
        """Records pushed into the current ring."""
        return self._ring.pushed

    @property
    def cursors(self) -> int:
        """Cursors attached now."""
        with self._lock:
            return len(self._cursors)

    # ------------------------------------------------------------------ writer

    def push(self, t: npt.NDArray[np.float64], records: npt.NDArray[Any]) -> None:
        """Append ``len(t)`` records (a structured array of this ring's dtype)."""
        if records.dtype != self.dtype:
            raise ValueError(f"{self.name}: records of {records.dtype}, ring holds {self.dtype}")
        with self._lock:
            self._ring.push_many(t, records)

    # ------------------------------------------------------------------ cursors

    def attach(self, limit: int) -> Cursor:
        """A new cursor seeing the samples pushed from now on, keeping at most ``limit``
        unread (bounded by the capacity)."""
        limit = max(1, min(int(limit), self.capacity))
        with self._lock:
            cursor = Cursor(self._ring.add_reader(limit), limit, 0, self._generation)
            self._cursors.append(cursor)
        return cursor

    def detach(self, cursor: Cursor) -> None:
        """Forget ``cursor`` (idempotent)."""
        with self._lock:
            if cursor in self._cursors:
                self._cursors.remove(cursor)
                self._ring.remove_reader(cursor.reader)

    def set_limit(self, cursor: Cursor, limit: int) -> None:
        """Change a cursor's capacity (a new subscribe by the same client); its unread
        samples are discarded (not counted as lost: the client asked anew)."""
        limit = max(1, min(int(limit), self.capacity))
        with self._lock:
            if cursor not in self._cursors:
                return
            cursor.lost_before += self._ring.lost(cursor.reader)
            self._ring.remove_reader(cursor.reader)
            cursor.reader, cursor.limit = self._ring.add_reader(limit), limit

    def available(self, cursor: Cursor) -> int:
        """Unread samples of ``cursor``."""
        with self._lock:
            return self._ring.available(cursor.reader)

    def lost(self, cursor: Cursor) -> int:
        """Samples dropped for ``cursor`` because it fell more than its limit behind."""
        with self._lock:
            return cursor.lost_before + self._ring.lost(cursor.reader)

    def read(self, cursor: Cursor) -> tuple[npt.NDArray[np.float64], npt.NDArray[Any]]:
        """Take every unread sample of ``cursor``: ``(t, records)``, oldest first (records is a
        structured array of :attr:`dtype`, one copy out of the ring)."""
        with self._lock:
            t, raw = self._ring.read(cursor.reader)
        return t, raw.view(self.dtype).reshape(len(t))

    # ------------------------------------------------------------------ settings

    def reshape(self, dtype: np.dtype[Any], capacity: int) -> None:
        """Replace the storage for records of another layout (a camera's new resolution).

        Every cursor is kept with its limit (bounded by the new capacity); the unread samples
        of the old layout are discarded and counted as lost.
        """
        with self._lock:
            old = self._ring
            self._make(dtype, capacity)
            self._generation += 1
            for c in self._cursors:
                c.lost_before += old.lost(c.reader) + old.available(c.reader)
                c.limit = min(c.limit, capacity)
                c.reader = self._ring.add_reader(c.limit)
                c.generation = self._generation
