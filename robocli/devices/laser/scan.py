"""What a scanner is (:class:`LaserInfo`, from VV/PP/II) and what it measures (:class:`Scan`).

A scan's ``ranges`` are metres (float64), NaN where the sensor sent an error code (any value
below DMIN: no return, too near, interference...) or a value beyond DMAX; ``codes`` keeps the
raw value there (0 where the range is valid). ``angles`` are radians, counter-clockwise,
0 straight ahead: ``(step - AFRT) * 2 pi / ARES`` for the first step of each cluster.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import overload

import numpy as np
import numpy.typing as npt

from robocli.errors import ProtocolError

__all__ = ["LaserInfo", "Scan"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


def _int(pp: dict[str, str], key: str) -> int:
    text = pp.get(key, "")
    try:
        return int(text.split("(")[0].split("[")[0])
    except ValueError:
        raise ProtocolError(f"SCIP PP {key}:{text!r} is not a number") from None


class _Param:
    """A whole-number parameter of the PP reply (``DMIN:20``, ``SCAN:600(rpm)``), read as an
    ``int`` attribute of :class:`LaserInfo`; a value that is not a number is a
    :class:`ProtocolError`."""

    def __init__(self, key: str) -> None:
        self.key = key

    @overload
    def __get__(self, info: None, owner: type) -> _Param: ...

    @overload
    def __get__(self, info: LaserInfo, owner: type) -> int: ...

    def __get__(self, info: LaserInfo | None, owner: type) -> int | _Param:
        return self if info is None else _int(info.pp, self.key)


@dataclass(frozen=True)
class LaserInfo:
    """The scanner's identity (VV), parameters (PP) and state (II), as the key/value lines."""

    vv: dict[str, str]
    pp: dict[str, str]
    ii: dict[str, str] = field(default_factory=dict)

    dmin = _Param("DMIN")
    """Smallest valid range, mm."""
    dmax = _Param("DMAX")
    """Largest valid range, mm."""
    ares = _Param("ARES")
    """Steps per full turn."""
    amin = _Param("AMIN")
    """First step measured."""
    amax = _Param("AMAX")
    """Last step measured."""
    afrt = _Param("AFRT")
    """The step straight ahead."""
    rpm = _Param("SCAN")
    """Turns per minute."""

    def __post_init__(self) -> None:
        for param in vars(LaserInfo).values():  # each one parses, or the reply is refused
            if isinstance(param, _Param):
                _int(self.pp, param.key)
        if self.ares <= 0 or self.rpm <= 0 or self.amax < self.amin:
            raise ProtocolError(f"SCIP PP parameters make no sense: {self.pp}")

    @property
    def model(self) -> str:
        return self.pp.get("MODL", "?")

    @property
    def serial(self) -> str:
        return self.vv.get("SERI", "?")

    @property
    def period(self) -> float:
        """Seconds per scan."""
        return 60.0 / self.rpm

    def angle(self, step: float) -> float:
        """Angle of ``step``, radians."""
        return (step - self.afrt) * 2.0 * math.pi / self.ares

    def as_dict(self) -> dict[str, object]:
        return {
            "model": self.model, "serial": self.serial, "vendor": self.vv.get("VEND", ""),
            "product": self.vv.get("PROD", ""), "firmware": self.vv.get("FIRM", ""),
            "protocol": self.vv.get("PROT", ""), "dmin_m": self.dmin / 1000.0,
            "dmax_m": self.dmax / 1000.0, "steps": [self.amin, self.amax],
            "angle_min": self.angle(self.amin), "angle_max": self.angle(self.amax),
            "scan_period_s": self.period,
        }  # fmt: skip


@dataclass(frozen=True, eq=False)
class Scan:
    """One scan. ``t``: host epoch seconds of step 0 (sensor stamp mapped to the host
    clock; the reception time before any clock estimate). ``stamp_ms``: the sensor's
    timestamp unwrapped (ms). ``received``: host epoch seconds when the reply arrived.
    ``steps``: the first step of each value; ``remaining``: an MD frame's count field."""

    t: float
    stamp_ms: int
    received: float
    ranges: FloatArray
    angles: FloatArray
    codes: IntArray
    steps: IntArray
    intensities: FloatArray | None = None
    command: str = "GD"
    remaining: int | None = None
    raw: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    @property
    def valid(self) -> npt.NDArray[np.bool_]:
        """Where the range is a distance (not an error code)."""
        out: npt.NDArray[np.bool_] = ~np.isnan(self.ranges)
        return out

    def as_dict(self) -> dict[str, object]:
        """JSON-ready: ranges (m, None for an error code), angles (rad), codes, times."""
        ranges = [None if math.isnan(r) else round(float(r), 4) for r in self.ranges]
        out: dict[str, object] = {
            "t": self.t, "stamp_ms": self.stamp_ms, "received": self.received,
            "angles": [round(float(a), 6) for a in self.angles], "ranges": ranges,
            "codes": [int(c) for c in self.codes],
        }  # fmt: skip
        if self.intensities is not None:
            out["intensities"] = [float(i) for i in self.intensities]
        return out


def make_scan(
    info: LaserInfo,
    *,
    raw: npt.ArrayLike,
    intensities: npt.ArrayLike | None,
    start: int,
    cluster: int,
    t: float,
    stamp_ms: int,
    received: float,
    command: str,
    remaining: int | None,
) -> Scan:
    """A :class:`Scan` from the decoded values of a reply."""
    values = np.asarray(raw, dtype=np.int64)
    c = max(cluster, 1)
    steps = start + np.arange(len(values), dtype=np.int64) * c
    bad = (values < info.dmin) | (values > info.dmax)
    ranges = np.where(bad, np.nan, values / 1000.0)
    codes = np.where(bad, values, 0)
    angles = ((steps - info.afrt) * (2.0 * math.pi / info.ares)).astype(np.float64)
    inten = None if intensities is None else np.asarray(intensities, dtype=np.float64)
    return Scan(t, stamp_ms, received, ranges, angles, codes, steps, inten, command,
                remaining, values)  # fmt: skip
