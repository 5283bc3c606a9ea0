"""User waypoints for ``robocli traj file``: joint angles or flange positions, from JSON or CSV.

JSON: ``{"joints": [[rad...]...]}``, ``{"joints_deg": [[deg...]...]}`` or
``{"points": [[x, y, z]...]}`` (m), with an optional ``"time": [...]`` (s); a trajectory log
(``joints_positions``) is accepted too. CSV: a header of ``q1..qn`` (rad), ``q1_deg..qn_deg``
or ``x,y,z`` (m), optionally ``time``, then one row per waypoint.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from robocli.kinematics.trajlog import LogFormatError, open_capped

FloatArray = npt.NDArray[np.float64]
MAX_WAYPOINT_BYTES = 64 * 1024 * 1024


@dataclass(frozen=True)
class Waypoints:
    """Either ``joints`` (N x n rad) or ``points`` (N x 3 m), and optional ``time`` (N s)."""

    joints: FloatArray | None
    points: FloatArray | None
    time: FloatArray | None


def read_waypoints(path: str | Path) -> Waypoints:
    """Read waypoints from a ``.json`` or ``.csv`` file (raises :class:`LogFormatError`)."""
    src = Path(path)
    suffix = src.suffix.lower()
    if suffix not in (".json", ".csv"):
        raise LogFormatError(f"{src}: waypoints come from a .json or .csv file")
    try:
        if src.stat().st_size > MAX_WAYPOINT_BYTES:
            raise LogFormatError(f"{src}: a waypoint file is at most 64 MiB")
        fh = open_capped(src, MAX_WAYPOINT_BYTES, "a waypoint file")
        wp = _from_csv(fh) if suffix == ".csv" else _from_json(fh)
    except RecursionError:
        raise LogFormatError(f"{src}: not waypoints (JSON nested too deeply)") from None
    except OSError as exc:
        raise LogFormatError(f"{src}: cannot read ({exc.strerror})") from exc
    except (UnicodeDecodeError, ValueError, csv.Error) as exc:  # csv: a bare CR in a field
        if isinstance(exc, LogFormatError):
            if str(exc).startswith(f"{src}:"):
                raise
            raise LogFormatError(f"{src}: {exc}") from None
        raise LogFormatError(f"{src}: not valid {suffix[1:].upper()} ({exc})") from None
    for name, arr in (("joints", wp.joints), ("points", wp.points), ("time", wp.time)):
        if arr is not None and not np.all(np.isfinite(arr)):
            raise LogFormatError(f"{src}: {name} hold a NaN or an infinity")
    if wp.points is not None and (wp.points.ndim != 2 or wp.points.shape[1] != 3):
        raise LogFormatError(f"{src}: points are rows of x, y, z")
    rows = wp.joints if wp.joints is not None else wp.points
    if rows is None or rows.shape[0] < 2:
        raise LogFormatError(f"{src}: at least two waypoints are needed")
    if wp.time is not None and wp.time.shape != (rows.shape[0],):
        raise LogFormatError(f"{src}: one time per waypoint")
    return wp


def _rows(key: str, value: Any) -> FloatArray:
    if not isinstance(value, list) or not all(isinstance(r, list) for r in value):
        raise LogFormatError(f"{key!r} must be a list of rows")
    widths = {len(r) for r in value}
    if len(widths) > 1:
        raise LogFormatError(f"{key!r} has rows of different lengths (ragged rows)")
    try:
        return np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise LogFormatError(f"{key!r} holds something that is not a number") from None


def _reject(token: str) -> float:
    raise LogFormatError(f"holds {token}: waypoints are finite numbers")


def _from_json(fh: Any) -> Waypoints:
    doc = json.load(fh, parse_constant=_reject)
    if not isinstance(doc, dict):
        raise LogFormatError("waypoints are a JSON object")
    time = None
    if doc.get("time") is not None:
        try:
            time = np.asarray(doc["time"], dtype=float)
        except (TypeError, ValueError):
            raise LogFormatError("'time' holds something that is not a number") from None
    if "joints_deg" in doc:
        return Waypoints(np.radians(_rows("joints_deg", doc["joints_deg"])), None, time)
    for key in ("joints", "joints_positions"):
        if key in doc:
            return Waypoints(_rows(key, doc[key]), None, time)
    if "points" in doc:
        return Waypoints(None, _rows("points", doc["points"]), time)
    raise LogFormatError("waypoints need a 'joints', 'joints_deg' or 'points' key")


def _from_csv(fh: Any) -> Waypoints:
    reader = csv.reader(fh)
    header = [h.strip() for h in next(reader, [])]
    data = []
    for lineno, row in enumerate(reader, start=2):
        if not row:
            continue
        if len(row) != len(header):
            raise LogFormatError(f"line {lineno} has {len(row)} values, expected {len(header)}")
        try:
            data.append([float(v) for v in row])
        except ValueError:
            raise LogFormatError(f"line {lineno} holds something that is not a number") from None
    arr = np.asarray(data, dtype=float).reshape(len(data), len(header))
    time = arr[:, header.index("time")] if "time" in header else None
    deg = [i for i, h in enumerate(header) if h.startswith("q") and h.endswith("_deg")]
    rad = [i for i, h in enumerate(header) if h.startswith("q") and h[1:].isdigit()]
    xyz = [header.index(c) for c in ("x", "y", "z") if c in header]
    if deg:
        return Waypoints(arr[:, deg] * (math.pi / 180.0), None, time)
    if rad:
        return Waypoints(arr[:, rad], None, time)
    if len(xyz) == 3:
        return Waypoints(None, arr[:, xyz], time)
    raise LogFormatError("CSV header needs q1..qn, q1_deg..qn_deg or x,y,z")
