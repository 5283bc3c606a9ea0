"""Serial robots described by small JSON model files (standard DH), shipped with the package.

A new robot is a new file in ``robocli/kinematics/models/``, not new code: ``load_model``
accepts a shipped model's name or the path of any model file of the same layout.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from functools import cached_property
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from robocli.kinematics.errors import ModelFileError, UnknownModelError

FloatArray = npt.NDArray[np.float64]

MAX_MODEL_BYTES = 64 * 1024
MAX_JOINTS = 12
_ANALYTIC_TOL = 1e-12


@dataclass(frozen=True)
class ReferencePose:
    """A published pose: joint angles (rad) and the flange position they give (m)."""

    joints: FloatArray
    tcp: FloatArray
    source: str


@dataclass(frozen=True)
class RobotModel:
    """A serial robot in standard Denavit-Hartenberg form. Lengths in m, angles in rad.

    Joint ``i`` contributes ``Rz(q_i + offset_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``; the tool point
    is the origin of the last frame (the flange).
    """

    name: str
    title: str
    source: str
    a: FloatArray
    d: FloatArray
    alpha: FloatArray
    offset: FloatArray
    limits: FloatArray  # (n, 2): lower, upper (rad)
    max_speed: FloatArray  # (n,) rad/s
    home: FloatArray
    work: FloatArray
    reference_poses: tuple[ReferencePose, ...] = field(default=())

    @property
    def n_joints(self) -> int:
        """Number of joints."""
        return int(self.a.shape[0])

    @cached_property
    def spherical_wrist(self) -> bool:
        """True when the closed-form 6R solution applies: a 6R arm whose last three axes
        meet in one point, with a shoulder and elbow like the IRB120 (alpha1 = +-90 deg,
        alpha2 = 0, alpha3..5 = +-90 deg, a4 = a5 = a6 = d5 = 0)."""
        if self.n_joints != 6:
            return False
        s = np.sin(self.alpha)
        return bool(
            abs(abs(s[0]) - 1) < _ANALYTIC_TOL
            and abs(self.alpha[1]) < _ANALYTIC_TOL
            and all(abs(abs(s[i]) - 1) < _ANALYTIC_TOL for i in (2, 3, 4))
            and all(abs(self.a[i]) < _ANALYTIC_TOL for i in (3, 4, 5))
            and abs(self.d[4]) < _ANALYTIC_TOL
        )

    def within_limits(self, q: npt.ArrayLike) -> npt.NDArray[np.bool_]:
        """Element-wise: is each joint value inside its range (``q``: (..., n) rad)?"""
        arr = np.asarray(q, dtype=float)
        return (arr >= self.limits[:, 0]) & (arr <= self.limits[:, 1])


def known_models() -> list[str]:
    """Names of the model files shipped with robocli."""
    folder = resources.files("robocli.kinematics") / "models"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".json"))


def load_model(name_or_path: str | Path) -> RobotModel:
    """Load a shipped model by name (``"irb120"``) or any model file by path.

    Raises :class:`UnknownModelError` (listing the known names) or :class:`ModelFileError`.
    """
    text_name = str(name_or_path)
    if text_name.endswith(".json") or "/" in text_name or "\\" in text_name:
        path = Path(text_name)
        try:
            with path.open("rb") as fh:  # bounded, even where stat has no size (/dev/zero)
                raw = fh.read(MAX_MODEL_BYTES + 1)
        except OSError as exc:
            raise ModelFileError(f"{path}: cannot read model file ({exc.strerror})") from exc
        return parse_model(raw, str(path))
    key = text_name.strip().lower().replace("-", "").replace("_", "").replace(" ", "")
    known = known_models()
    if key not in known:
        raise UnknownModelError(
            f"unknown robot model {text_name!r}; known models: {', '.join(known)}"
        )
    raw = (resources.files("robocli.kinematics") / "models" / f"{key}.json").read_bytes()
    return parse_model(raw, key)


def parse_model(raw: bytes, where: str) -> RobotModel:
    """Build a :class:`RobotModel` from the bytes of a model file (``where`` names it)."""
    if len(raw) > MAX_MODEL_BYTES:
        raise ModelFileError(f"{where}: a model file is at most {MAX_MODEL_BYTES} bytes")
    try:
        doc = json.loads(raw)
    except (ValueError, UnicodeDecodeError) as exc:
        raise ModelFileError(f"{where}: not valid JSON ({exc})") from exc
    except RecursionError:
        raise ModelFileError(f"{where}: not a model (JSON nested too deeply)") from None
    if not isinstance(doc, dict):
        raise ModelFileError(f"{where}: a model file is a JSON object")
    try:
        dh = _get(doc, "dh", dict, where)
        a = _vector(dh, "a", where)
        n = a.shape[0]
        if not 1 <= n <= MAX_JOINTS:
            raise ModelFileError(f"{where}: 1 to {MAX_JOINTS} joints, not {n}")
        d = _vector(dh, "d", where, n)
        alpha = np.radians(_vector(dh, "alpha_deg", where, n))
        offset = np.radians(_vector(dh, "offset_deg", where, n))
        limits = np.radians(_matrix(doc, "limits_deg", where, n, 2))
        if np.any(limits[:, 0] >= limits[:, 1]):
            raise ModelFileError(f"{where}: each joint limit is [lower, upper] with lower < upper")
        speed = np.radians(_vector(doc, "max_speed_deg_s", where, n))
        if np.any(speed <= 0):
            raise ModelFileError(f"{where}: max_speed_deg_s must be positive")
        home = np.radians(_vector(doc, "home_deg", where, n))
        work = np.radians(_vector(doc, "work_deg", where, n)) if "work_deg" in doc else home
        refs = []
        for i, ref in enumerate(doc.get("reference_poses", [])):
            if not isinstance(ref, dict):
                raise ModelFileError(f"{where}: reference_poses[{i}] is not an object")
            refs.append(
                ReferencePose(
                    joints=np.radians(_vector(ref, "joints_deg", where, n)),
                    tcp=_vector(ref, "tcp_m", where, 3),
                    source=str(ref.get("source", "")),
                )
            )
        name = str(_get(doc, "name", str, where))
    except (TypeError, ValueError) as exc:
        if isinstance(exc, ModelFileError):
            raise
        raise ModelFileError(f"{where}: {exc}") from exc
    return RobotModel(
        name=name,
        title=str(doc.get("title", name)),
        source=str(doc.get("source", "")),
        a=a,
        d=d,
        alpha=alpha,
        offset=offset,
        limits=limits,
        max_speed=speed,
        home=home,
        work=work,
        reference_poses=tuple(refs),
    )


def _get(doc: dict[str, Any], key: str, kind: type, where: str) -> Any:
    if key not in doc:
        raise ModelFileError(f"{where}: missing key {key!r}")
    value = doc[key]
    if not isinstance(value, kind):
        raise ModelFileError(f"{where}: {key!r} must be a {kind.__name__}")
    return value


def _vector(doc: dict[str, Any], key: str, where: str, n: int | None = None) -> FloatArray:
    values = _get(doc, key, list, where)
    if n is not None and len(values) != n:
        raise ModelFileError(f"{where}: {key!r} has {len(values)} values, expected {n}")
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        raise ModelFileError(f"{where}: {key!r} must hold numbers")
    arr = np.asarray(values, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ModelFileError(f"{where}: {key!r} holds a NaN or an infinity")
    return arr


def _matrix(doc: dict[str, Any], key: str, where: str, n: int, m: int) -> FloatArray:
    rows = _get(doc, key, list, where)
    if len(rows) != n or not all(isinstance(r, list) and len(r) == m for r in rows):
        raise ModelFileError(f"{where}: {key!r} must be {n} rows of {m} numbers")
    return np.stack([_vector({key: r}, key, where, m) for r in rows])


def deg(values: npt.ArrayLike) -> list[float]:
    """Radians to a plain list of degrees (for messages)."""
    return [math.degrees(float(v)) for v in np.ravel(np.asarray(values, dtype=float))]
