"""Simulated low-rate sensors: ADC (IR range + gyro), IMU, GPS, battery.

Each is deterministic for a given seed and start time, so tests can check shapes and values.
Units are the ros4mat wire units (volts, g, deg/s, uT, degrees, m/s).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from robocli.hub_server.sources.base import PeriodicSource, rate_param
from robocli.protocols.ros4mat import GpsState, record_dtype
from robocli.sim.world import World

__all__ = ["AdcSource", "BatterySource", "GpsSource", "ImuSource", "batch_rate"]

MAX_BATCH_HZ = 100.0  #: a driver polls its source at most this often


def batch_rate(params: Mapping[str, Any], rate: float, key: str = "freq_send") -> float:
    """Polls per second: the ``freq_send`` parameter (default ``rate/4 + 10``, the original
    client's), at most ``rate`` and :data:`MAX_BATCH_HZ`, at least 1 Hz."""
    wanted = float(params.get(key) or math.floor(rate / 4 + 10))
    return max(1.0, min(wanted, rate, MAX_BATCH_HZ))


class _RecordSource(PeriodicSource):
    """A simulated sensor with a fixed ros4mat record and ``freq_acquisition``/``freq_send``
    parameters; subclasses set :attr:`RECORD`, the rates and a seed for their noise."""

    RECORD = ""
    DEFAULT_RATE = 100.0
    MAX_RATE = 1000.0
    SEED = 0

    def __init__(self, seed: int | None = None) -> None:
        self._rng = np.random.default_rng(self.SEED if seed is None else seed)
        super().__init__()

    def configure(self, params: Mapping[str, Any]) -> None:
        self.rate = rate_param(params, "freq_acquisition", self.DEFAULT_RATE, self.MAX_RATE)
        self.batch_rate = batch_rate(params, self.rate)
        self.params = {}

    def dtype(self) -> np.dtype[Any]:
        return record_dtype(self.RECORD)


class AdcSource(_RecordSource):
    """An 8-channel ADC (DATAQ DI-149-like, volts) set up as the ros4mat paper's polar-map
    experiment: a platform turning at :attr:`OMEGA_DEG` deg/s in a corner of the Pioneer
    simulator's default room carries an infrared range sensor (channel 0, Sharp-like
    ``V = a / (d + b)`` from 0.15 to 1.5 m) and a rate gyro (channel 1, 2.5 V at rest,
    12.5 mV per deg/s). Channels 2..7 are sines of 0.5..3 Hz; channels outside the mask read 0.
    The four digital outputs (DOUT_CTRL) are kept in :attr:`digital`.
    """

    name = "adc"
    RECORD = "adc"
    MAX_RATE = 10000.0
    SEED = 1
    OMEGA_DEG = 30.0
    POSITION = (-3.0, 3.8)
    IR_A, IR_B = 0.632, 0.0798
    GYRO_ZERO, GYRO_GAIN = 2.5, 0.0125

    def __init__(self, seed: int | None = None) -> None:
        self._world = World.default()
        self.digital = [0, 0, 0, 0]
        super().__init__(seed)

    def configure(self, params: Mapping[str, Any]) -> None:
        super().configure(params)
        mask = int(params.get("channels", 0xFF)) & 0xFF
        self.params = {"channels": mask or 0xFF}

    def heading(self, t: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """The platform's true heading (rad) at times ``t``."""
        heading: npt.NDArray[np.float64] = np.radians(self.OMEGA_DEG) * (t % (360 / self.OMEGA_DEG))
        return heading

    def ir_volts(self, distance: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """The IR sensor's output for a range (m), saturating outside 0.15..1.5 m."""
        return self.IR_A / (np.clip(distance, 0.15, 1.5) + self.IR_B)

    def sample(self, t: npt.NDArray[np.float64]) -> npt.NDArray[Any]:
        n = len(t)
        rec = np.zeros(n, dtype=self.dtype())
        rec["t"] = t
        ch = np.empty((n, 8), dtype=np.float64)
        x, y = self.POSITION
        d = self._world.cast(np.full(n, x), np.full(n, y), self.heading(t), 5.0)
        ch[:, 0] = self.ir_volts(d) + self._rng.normal(0, 0.01, n)
        ch[:, 1] = self.GYRO_ZERO + self.GYRO_GAIN * (self.OMEGA_DEG + self._rng.normal(0, 0.5, n))
        for k in range(2, 8):
            ch[:, k] = 2.5 + 2.0 * np.sin(2 * np.pi * 0.5 * (k - 1) * t)
        mask = self.params["channels"]
        for k in range(8):
            if not mask >> k & 1:
                ch[:, k] = 0.0
        rec["channels"] = ch
        return rec

    def settings(self) -> dict[str, Any]:
        return {**super().settings(), "digital_out": list(self.digital)}


class ImuSource(_RecordSource):
    """A 9-axis IMU (Phidgets-like): accelerometer (g), gyro (deg/s), magnetometer (uT), each
    with a constant bias and white noise, on a platform that sways and turns slowly."""

    name = "imu"
    RECORD = "imu"
    SEED = 2
    ACC_BIAS = np.array([0.01, -0.02, 0.005])
    GYRO_BIAS = np.array([0.3, -0.2, 0.5])
    MAG_FIELD = np.array([18.0, 0.0, -48.0])  # uT, Quebec City: north and down

    def sample(self, t: npt.NDArray[np.float64]) -> npt.NDArray[Any]:
        n, rng = len(t), self._rng
        rec = np.zeros(n, dtype=self.dtype())
        rec["t"] = t
        roll = np.radians(5.0) * np.sin(2 * np.pi * 0.2 * t)
        yaw = np.radians(45.0) * np.sin(2 * np.pi * 0.05 * t)
        acc = np.stack([np.zeros(n), np.sin(roll), np.cos(roll)], axis=1)
        rec["acc"] = acc + self.ACC_BIAS + rng.normal(0, 0.005, (n, 3))
        rates = np.zeros((n, 3))
        rates[:, 0] = np.degrees(np.radians(5.0) * 2 * np.pi * 0.2 * np.cos(2 * np.pi * 0.2 * t))
        rates[:, 2] = np.degrees(np.radians(45.0) * 2 * np.pi * 0.05 * np.cos(2 * np.pi * 0.05 * t))
        rec["gyro"] = rates + self.GYRO_BIAS + rng.normal(0, 0.2, (n, 3))
        c, s = np.cos(yaw), np.sin(yaw)
        fx, fy, fz = self.MAG_FIELD
        mag = np.stack([c * fx + s * fy, -s * fx + c * fy, np.full(n, fz)], axis=1)
        rec["mag"] = mag + rng.normal(0, 0.3, (n, 3))
        return rec


class GpsSource(_RecordSource):
    """A 3-D GPS fix walking a 50 m circle at 1.4 m/s around Universite Laval."""

    name = "gps"
    RECORD = "gps"
    DEFAULT_RATE, MAX_RATE = 1.0, 20.0
    SEED = 3
    ORIGIN = (46.7817, -71.2747, 90.0)
    RADIUS, SPEED = 50.0, 1.4

    def sample(self, t: npt.NDArray[np.float64]) -> npt.NDArray[Any]:
        n = len(t)
        rec = np.zeros(n, dtype=self.dtype())
        rec["t"] = t
        phase = self.SPEED / self.RADIUS * t
        north = self.RADIUS * np.sin(phase) + self._rng.normal(0, 1.5, n)
        east = self.RADIUS * np.cos(phase) + self._rng.normal(0, 1.5, n)
        lat0, lon0, alt0 = self.ORIGIN
        rec["state"] = GpsState.FIX_3D
        rec["latitude"] = lat0 + np.degrees(north / 6371000.0)
        rec["longitude"] = lon0 + np.degrees(east / (6371000.0 * math.cos(math.radians(lat0))))
        rec["altitude"] = alt0 + self._rng.normal(0, 3.0, n)
        rec["speed"] = self.SPEED
        rec["track"] = (np.degrees(-phase) + 360.0) % 360.0  # clockwise in (east, north)
        rec["climb"] = 0.0
        return rec


class BatterySource(_RecordSource):
    """A 3-cell LiPo pack discharging at 2 A (state of charge falling 1 %/min, recharged at
    20 %), robocli's BATTERY record (0x22)."""

    name = "battery"
    RECORD = "battery"
    DEFAULT_RATE, MAX_RATE = 1.0, 100.0
    SEED = 4
    CELLS = 3

    def sample(self, t: npt.NDArray[np.float64]) -> npt.NDArray[Any]:
        n, k = len(t), self.CELLS
        rec = np.zeros(n, dtype=self.dtype())
        rec["t"] = t
        soc = 1.0 - (t / 60.0 * 0.01) % 0.8
        cells = 3.3 + 0.9 * soc[:, None] + self._rng.normal(0, 0.003, (n, k))
        vcell = np.zeros((n, 8))
        vcell[:, :k] = cells
        rec["vcell"] = vcell
        rec["n_cells"] = k
        rec["vtotal"] = cells.sum(axis=1)
        rec["current"] = 2.0 + self._rng.normal(0, 0.05, n)
        rec["state_of_charge"] = soc
        rec["state"] = np.where(cells.min(axis=1) < 3.4, 1, 0)
        return rec
