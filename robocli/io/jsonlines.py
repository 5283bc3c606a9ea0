"""JSON-ready data as every ``--json`` output gives it: floats rounded to the protocol's
resolution (no ``0.9590000000000001`` noise), NaN as null, ``time.monotonic()`` readings as
Unix time."""

from __future__ import annotations

import math
import time
from typing import Any

__all__ = ["RESOLUTION", "json_default", "rounded", "unix_stamped"]

#: Decimals kept in JSON output, by field name: the protocol's resolution in SI units
#: (odometry 0.485 mm and 2*pi/4096 rad, speeds 1 mm/s and 0.1 deg/s, battery 0.1 V...).
RESOLUTION = {
    "t": 6, "t_mono": 6, "x": 4, "y": 4, "th": 4, "v": 3, "w": 4, "left_velocity": 3,
    "right_velocity": 3, "battery": 1, "state_of_charge": 2, "sonar": 3, "analog": 3,
    "temperature": 1, "ranges": 3, "angles": 4, "range": 3, "angle": 4,
}  # fmt: skip


def rounded(data: Any, digits: int = 6, resolution: dict[str, int] = RESOLUTION) -> Any:
    """``data`` with every float rounded to its field's decimals in ``resolution`` (else
    ``digits``): no ``0.9590000000000001`` noise in JSON. NaN and infinities become None."""
    if isinstance(data, float):
        return round(data, digits) if math.isfinite(data) else None
    if isinstance(data, dict):
        return {k: rounded(v, resolution.get(str(k), digits), resolution) for k, v in data.items()}
    if isinstance(data, (list, tuple)):
        return [rounded(v, digits, resolution) for v in data]
    if hasattr(data, "tolist"):
        return rounded(data.tolist(), digits, resolution)
    return data


def unix_stamped(data: dict[str, Any], key: str = "t") -> dict[str, Any]:
    """``data`` with its ``time.monotonic()`` reading ``key`` given as Unix time (s), the one
    time base of every ``--json`` output, and the monotonic reading kept as ``t_mono``."""
    out: dict[str, Any] = {}
    for k, v in data.items():
        if k == key and isinstance(v, (int, float)):
            out[k] = v + time.time() - time.monotonic()
            out["t_mono"] = v
        else:
            out[k] = v
    return out


def json_default(obj: Any) -> Any:
    """``json.dumps``'s ``default``: arrays and tuples as lists, anything else as text."""
    if hasattr(obj, "tolist"):
        return obj.tolist()
    if isinstance(obj, (set, frozenset, tuple)):
        return list(obj)
    return str(obj)
