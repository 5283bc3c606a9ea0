"""The one interface of every hub source: configure, start, poll timestamped records, stop.

A source knows only how to produce records of one sensor: a NumPy structured array of its
:meth:`Source.dtype` and the acquisition time of each (seconds on the hub's clock). It knows
nothing of rings, clients or wire protocols. Sources whose records carry variable-size blobs
(images, scans) declare their blob fields in :attr:`Source.blobs` and report the used length
of each blob with :meth:`Source.blob_sizes`; the rest of each blob field is padding.

:class:`PeriodicSource` is the base of sampled sensors: it computes the sample times
``t0 + k / rate`` due since the last poll and asks :meth:`PeriodicSource.sample` for them.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt

from robocli.errors import InvalidArgument

__all__ = ["Batch", "PeriodicSource", "Source", "rate_param"]

Batch = tuple[npt.NDArray[np.float64], npt.NDArray[Any]]
"""``(t, records)``: acquisition times (float64, shape (n,)) and n structured records."""

EMPTY_T = np.empty(0, dtype=np.float64)
MAX_CATCH_UP_S = 1.0  #: a periodic source late by more than this skips the missed samples


def rate_param(params: Mapping[str, Any], key: str, default: float, top: float) -> float:
    """``params[key]`` as a rate in Hz: ``default`` when absent or 0, an
    :class:`InvalidArgument` naming the key when above ``top``."""
    value = float(params.get(key) or default)
    if not 0 < value <= top:
        raise InvalidArgument(f"{key} must be in 1..{top:g} Hz, not {value:g}")
    return value


class Source:
    """A producer of timestamped records for one sensor.

    Subclasses set :attr:`name` (the CLI's sensor name) and :attr:`kind` (a sensor kind
    shared by simulated and real sources, e.g. ``"gps"``), implement :meth:`configure`,
    :meth:`dtype` and :meth:`poll`; :meth:`start` / :meth:`stop` when they hold resources.
    """

    name: ClassVar[str] = ""
    blobs: ClassVar[tuple[str, ...]] = ()
    simulated: ClassVar[bool] = True

    def __init__(self) -> None:
        self.params: dict[str, Any] = {}
        self.clock: Callable[[], float] = time.time  #: the hub's clock (set by the hub)
        self.rate = 1.0  #: samples per second
        self.batch_rate = 1.0  #: polls per second
        self.configure({})

    def configure(self, params: Mapping[str, Any]) -> None:
        """Apply subscribe parameters (a dict of the sensor's params, possibly empty: the
        defaults). Raises :class:`InvalidArgument` naming a bad parameter."""
        raise NotImplementedError

    def dtype(self) -> np.dtype[Any]:
        """The structured dtype of one record under the current parameters."""
        raise NotImplementedError

    def start(self, t0: float) -> None:
        """Start producing; ``t0`` is the hub clock now."""

    def poll(self, now: float) -> Batch:
        """The records acquired since the last poll (times <= ``now``)."""
        raise NotImplementedError

    def stop(self) -> None:
        """Release what :meth:`start` took (idempotent)."""

    def blob_sizes(self, records: npt.NDArray[Any]) -> npt.NDArray[np.int64]:
        """Used bytes of each blob field of each record, shape ``(n, len(blobs))``."""
        return np.zeros((len(records), 0), dtype=np.int64)

    def settings(self) -> dict[str, Any]:
        """What a status display shows: rate, batch rate and the parameters."""
        return {"rate": self.rate, "batch_rate": self.batch_rate, **self.params}

    def empty(self) -> Batch:
        return EMPTY_T, np.empty(0, dtype=self.dtype())


class PeriodicSource(Source):
    """A sampled sensor: records at ``t0 + k / rate``, generated in batches at each poll."""

    def start(self, t0: float) -> None:
        self._t0 = t0
        self._k = 0

    def poll(self, now: float) -> Batch:
        due = math.floor((now - self._t0) * self.rate) + 1
        n = due - self._k
        if n <= 0:
            return self.empty()
        late = n / self.rate
        if late > MAX_CATCH_UP_S:  # stalled (suspended, overloaded): skip, do not flood
            skip = n - max(1, int(MAX_CATCH_UP_S * self.rate))
            self._k += skip
            n -= skip
        t = self._t0 + (self._k + np.arange(n, dtype=np.float64)) / self.rate
        self._k += n
        return t, self.sample(t)

    def sample(self, t: npt.NDArray[np.float64]) -> npt.NDArray[Any]:
        """The records acquired at times ``t`` (their ``t`` fields set to ``t``)."""
        raise NotImplementedError
