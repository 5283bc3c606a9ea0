"""Worlds of the robot simulators: walls as 2-D line segments, ray casting and clearance.

A :class:`World` is immutable: an ``(N, 4)`` array of wall segments ``x1, y1, x2, y2`` in
metres and a start pose ``(x, y, th)`` (m, m, rad). Queries are NumPy-vectorised over all walls
(and over all rays), so 16 sonars x 3 rays against hundreds of walls cost tens of microseconds.

Map files (:meth:`World.load`):

* JSON: ``{"walls": [[x1, y1, x2, y2], ...], "start": [x, y, th]}`` (``start`` optional,
  ``th`` in radians);
* text: one wall per line ``x1 y1 x2 y2``, an optional ``start x y th`` line, ``#`` comments.

Coordinates are finite and within :data:`MAX_COORD_M` of the origin; a file holds at most
:data:`MAX_MAP_BYTES`.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from robocli.errors import EXIT_USAGE, RobocliError

FloatArray = npt.NDArray[np.float64]

__all__ = ["MAX_COORD_M", "MAX_MAP_BYTES", "MapError", "World"]

#: Largest coordinate a map may hold (m): ray casting squares lengths, and a world much
#: larger than a building only overflows them.
MAX_COORD_M = 1e6
#: Largest map file read (bytes): a building of 100,000 walls fits in a few MiB.
MAX_MAP_BYTES = 16 * 2**20


class MapError(RobocliError, ValueError):
    """A map file that cannot be read or does not describe a world."""

    exit_code = EXIT_USAGE


def _as_walls(segments: Iterable[Sequence[float]] | FloatArray) -> FloatArray:
    walls = np.array(segments, dtype=np.float64).reshape(-1, 4)
    if not np.all(np.isfinite(walls)):
        raise MapError("wall coordinates must be finite numbers")
    if walls.size and np.abs(walls).max() > MAX_COORD_M:
        raise MapError(f"wall coordinates must lie within {MAX_COORD_M:g} m of the origin")
    walls.setflags(write=False)
    return walls


@dataclass(frozen=True, eq=False)
class World:
    """Static 2-D world: wall segments (m) and a start pose (m, m, rad)."""

    walls: FloatArray = field(default_factory=lambda: _as_walls([]))
    start: tuple[float, float, float] = (0.0, 0.0, 0.0)
    name: str = "custom"

    # ------------------------------------------------------------------ construction

    @classmethod
    def from_segments(
        cls,
        segments: Iterable[Sequence[float]],
        start: tuple[float, float, float] = (0.0, 0.0, 0.0),
        name: str = "custom",
    ) -> World:
        """A world from ``[(x1, y1, x2, y2), ...]`` in metres."""
        pose = (float(start[0]), float(start[1]), float(start[2]))
        return cls(_as_walls(list(segments)), pose, name)

    @classmethod
    def empty(cls) -> World:
        """No walls: every sonar reads its maximum range (like MobileSim's ``--nomap``)."""
        return cls(name="empty")

    @classmethod
    def default(cls) -> World:
        """A 12 m x 10 m room (x -4..8, y -5..5) with a few boxes; start (0, 0, 0) looks down
        a corridor free for ~7.5 m along +x."""
        segs: list[tuple[float, float, float, float]] = []
        segs += _box(-4.0, -5.0, 8.0, 5.0)  # the room
        segs += _box(4.5, 2.0, 5.5, 3.0)  # boxes, all clear of the line y = 0
        segs += _box(-3.0, -3.4, -2.2, -2.6)
        segs += _box(1.4, -3.8, 2.6, -3.2)
        segs += _box(5.8, -2.2, 6.2, -1.8)
        segs += _box(-2.5, 2.5, -1.5, 3.5)
        return cls.from_segments(segs, name="default")

    @classmethod
    def load(cls, path: str | Path) -> World:
        """Read a JSON or text map (see the module docstring)."""
        p = Path(path)
        try:
            with p.open("rb") as f:
                data = f.read(MAX_MAP_BYTES + 1)
        except OSError as exc:
            raise MapError(f"cannot read map {p}: {exc.strerror or exc}") from exc
        if len(data) > MAX_MAP_BYTES:
            raise MapError(f"{p}: larger than {MAX_MAP_BYTES // 2**20} MiB, not a map")
        text = data.decode("utf-8")  # UnicodeDecodeError: the CLI names the byte
        try:
            if p.suffix.lower() == ".json" or text.lstrip().startswith("{"):
                return _parse_json(text, p)
            return _parse_text(text, p)
        except MapError as exc:
            if str(p) in str(exc):
                raise
            raise MapError(f"{p}: {exc}") from exc

    # ------------------------------------------------------------------ queries

    def cast(
        self, ox: FloatArray, oy: FloatArray, angles: FloatArray, max_range: float
    ) -> FloatArray:
        """Distance along each ray (origin ``ox, oy``, direction ``angles``) to the first wall,
        ``max_range`` where nothing is hit closer."""
        out = np.full(np.shape(angles), max_range, dtype=np.float64)
        if len(self.walls) == 0 or out.size == 0:
            return out
        dx = np.cos(angles)[:, None]
        dy = np.sin(angles)[:, None]
        ax, ay, bx, by = (self.walls[:, i][None, :] for i in range(4))
        ex, ey = bx - ax, by - ay
        wx, wy = ax - np.asarray(ox)[:, None], ay - np.asarray(oy)[:, None]
        denom = dx * ey - dy * ex
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (wx * ey - wy * ex) / denom
            u = (wx * dy - wy * dx) / denom
        hit = (np.abs(denom) > 1e-12) & (t >= 0.0) & (u >= 0.0) & (u <= 1.0)
        t = np.where(hit, t, np.inf)
        result: FloatArray = np.minimum(t.min(axis=1), max_range)
        return result

    def nearest(self, x: float, y: float) -> tuple[float, float, float]:
        """``(distance, px, py)``: the wall point nearest to ``(x, y)`` (inf if no walls)."""
        if len(self.walls) == 0:
            return math.inf, x, y
        ax, ay, bx, by = (self.walls[:, i] for i in range(4))
        ex, ey = bx - ax, by - ay
        len2 = ex * ex + ey * ey
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.where(len2 > 0, ((x - ax) * ex + (y - ay) * ey) / len2, 0.0)
        s = np.clip(s, 0.0, 1.0)
        px, py = ax + s * ex, ay + s * ey
        d2 = (px - x) ** 2 + (py - y) ** 2
        i = int(np.argmin(d2))
        return math.sqrt(float(d2[i])), float(px[i]), float(py[i])

    def clearance(self, x: float, y: float) -> float:
        """Distance (m) from ``(x, y)`` to the nearest wall (inf if there are none)."""
        return self.nearest(x, y)[0]

    def sonar(
        self,
        pose: tuple[float, float, float],
        sensors: FloatArray,
        *,
        cone: float = math.radians(30.0),
        rays: int = 3,
        min_range: float = 0.1,
        max_range: float = 5.0,
    ) -> FloatArray:
        """Range (m) of each sonar: ``sensors`` is ``(K, 3)`` rows ``x, y, th`` in the robot
        frame (m, m, rad). Each sonar casts ``rays`` rays spread over its ``cone`` and reports
        the nearest hit, clipped to ``[min_range, max_range]``."""
        x, y, th = pose
        c, s = math.cos(th), math.sin(th)
        sx = x + c * sensors[:, 0] - s * sensors[:, 1]
        sy = y + s * sensors[:, 0] + c * sensors[:, 1]
        offsets = np.linspace(-cone / 2, cone / 2, rays) if rays > 1 else np.zeros(1)
        angles = (th + sensors[:, 2])[:, None] + offsets[None, :]
        k = len(sensors)
        ranges = self.cast(np.repeat(sx, rays), np.repeat(sy, rays), angles.ravel(), max_range)
        result: FloatArray = np.clip(ranges.reshape(k, rays).min(axis=1), min_range, max_range)
        return result


def _box(x1: float, y1: float, x2: float, y2: float) -> list[tuple[float, float, float, float]]:
    return [(x1, y1, x2, y1), (x2, y1, x2, y2), (x2, y2, x1, y2), (x1, y2, x1, y1)]


def _start(value: Any, where: str) -> tuple[float, float, float]:
    try:
        x, y, th = (float(v) for v in value)
    except (TypeError, ValueError) as exc:
        raise MapError(f"{where}: start must be three numbers x y th, got {value!r}") from exc
    if not all(math.isfinite(v) for v in (x, y, th)):
        raise MapError(f"{where}: start must be finite")
    if max(abs(x), abs(y)) > MAX_COORD_M:
        raise MapError(f"{where}: start must lie within {MAX_COORD_M:g} m of the origin")
    return x, y, th


def _parse_json(text: str, path: Path) -> World:
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise MapError(f"{path}: not valid JSON ({exc.msg} at line {exc.lineno})") from exc
    except RecursionError:
        raise MapError(f"{path}: not a map (JSON nested too deeply)") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("walls"), list):
        raise MapError(f'{path}: expected an object with a "walls" list')
    walls = []
    for i, wall in enumerate(doc["walls"]):
        if not isinstance(wall, list) or len(wall) != 4:
            raise MapError(f"{path}: wall {i} must be [x1, y1, x2, y2], got {wall!r}")
        try:
            walls.append(tuple(float(v) for v in wall))
        except (TypeError, ValueError) as exc:
            raise MapError(f"{path}: wall {i} holds a non-number: {wall!r}") from exc
    start = _start(doc["start"], str(path)) if "start" in doc else (0.0, 0.0, 0.0)
    return World.from_segments(walls, start, name=path.stem)


def _parse_text(text: str, path: Path) -> World:
    walls: list[tuple[float, ...]] = []
    start = (0.0, 0.0, 0.0)
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        words = line.split()
        where = f"{path}:{lineno}"
        if words[0].lower() == "start":
            start = _start(words[1:], where)
            continue
        if len(words) != 4:
            raise MapError(f"{where}: expected 'x1 y1 x2 y2', got {raw.strip()!r}")
        try:
            walls.append(tuple(float(w) for w in words))
        except ValueError as exc:
            raise MapError(f"{where}: not a number in {raw.strip()!r}") from exc
    return World.from_segments(walls, start, name=path.stem)
