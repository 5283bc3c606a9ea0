"""A real (or simulated) Hokuyo scanner as the hub's ``laser`` sensor (ros4mat HOKUYO, 0x27),
through the :class:`~robocli.devices.laser.Laser` client.

The scanner streams (MD) from the first subscription to the last unsubscription; each scan
becomes one ``msgHokuyo`` record in the original client's shape: angle_min/max and the
increment (rad), the time between steps (s), range_min/max (m), ``t`` the scan's step 0 on
the hub's clock, and the ranges as float32 metres, 0 where the sensor sent an error code
(what the simulated laser sends for no return). The subscription's ``freq_acquisition``
picks the MD scan interval (a sensor only skips whole scans: 40 Hz on a UTM-30LX asked for
10 Hz sends every 4th).
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from robocli.hub_server.sources.base import Batch, Source, rate_param
from robocli.protocols.ros4mat import record_dtype
from robocli.transports import check_url

if TYPE_CHECKING:
    from robocli.devices.laser import Laser, Scan

__all__ = ["HokuyoSource"]

MAX_BEAMS = 1081  #: the blob holds this many float32 ranges (a URG-04LX uses 682 of them)
MAX_PENDING = 256  #: scans kept between two polls (older ones are dropped)


class HokuyoSource(Source):
    """The ``laser`` sensor from the Hokuyo at ``url``."""

    name = "laser"
    blobs = ("blob0",)
    simulated = False
    MAX_RATE = 40.0

    def __init__(self, url: str) -> None:
        self.url = check_url(url, what="laser")
        self._laser: Laser | None = None
        self._pending: deque[Scan] = deque(maxlen=MAX_PENDING)
        self._lock = threading.Lock()
        super().__init__()

    def configure(self, params: Mapping[str, Any]) -> None:
        self.rate = rate_param(params, "freq_acquisition", 10.0, self.MAX_RATE)
        self.batch_rate = self.rate
        self.params = {"laser": self.url, "beams": MAX_BEAMS}

    def dtype(self) -> np.dtype[Any]:
        return np.dtype([("info", record_dtype("hokuyo")), ("blob0", np.uint8, (MAX_BEAMS * 4,))])

    def start(self, t0: float) -> None:
        from robocli.devices.laser import Laser

        if self._laser is not None:
            return
        laser = Laser.connect(self.url)
        try:
            info = laser.info
            assert info is not None
            interval = min(9, max(0, round(1.0 / (self.rate * info.period)) - 1))
            first = max(info.amin, info.afrt - (MAX_BEAMS - 1) // 2)
            last = min(info.amax, first + MAX_BEAMS - 1)
            laser.add_listener(self._push, kind="scans")
            laser.start(first, last, interval=interval)
        except BaseException:
            laser.close()
            raise
        self._laser = laser
        self.params = {**self.params, "model": info.model, "interval": interval}

    def _push(self, scan: Scan) -> None:
        with self._lock:
            self._pending.append(scan)

    def stop(self) -> None:
        laser, self._laser = self._laser, None
        if laser is not None:
            laser.close()
        with self._lock:
            self._pending.clear()

    def poll(self, now: float) -> Batch:
        laser = self._laser
        if laser is None:
            return self.empty()
        laser.session.check()  # a lost laser is the subscription's error, not silence
        with self._lock:
            scans, self._pending = list(self._pending), deque(maxlen=MAX_PENDING)
        if not scans:
            return self.empty()
        rec = np.zeros(len(scans), dtype=self.dtype())
        shift = self.clock() - time.time()  # scan times are epoch seconds
        info = laser.info
        assert info is not None
        for i, scan in enumerate(scans):
            self._fill(rec[i], scan, shift, info.ares, info.rpm, info.dmin, info.dmax)
        t: npt.NDArray[np.float64] = rec["info"]["t"].astype(np.float64)
        return t, rec

    @staticmethod
    def _fill(rec: Any, scan: Scan, shift: float, ares: int, rpm: int, dmin: int,
              dmax: int) -> None:  # fmt: skip
        n = len(scan.ranges)
        step = 2.0 * math.pi / ares
        inc = step * (int(scan.steps[1] - scan.steps[0]) if n > 1 else 1)
        info = rec["info"]
        info["angle_min"], info["angle_max"] = scan.angles[0], scan.angles[-1]
        info["angle_increment"] = inc
        info["time_increment"] = 60.0 / (rpm * ares)
        info["range_min"], info["range_max"] = dmin / 1000.0, dmax / 1000.0
        info["t"], info["size_data"] = scan.t + shift, n * 4
        ranges = np.nan_to_num(scan.ranges, nan=0.0).astype("<f4")
        rec["blob0"][: n * 4] = ranges.view(np.uint8)

    def blob_sizes(self, records: npt.NDArray[Any]) -> npt.NDArray[np.int64]:
        return records["info"]["size_data"].astype(np.int64).reshape(-1, 1)
