"""Fuzz harness of the file readers a user feeds robocli: trajectory logs (``.json``,
``.csv``, ``.npz``: :func:`robocli.kinematics.trajlog.read_log`), waypoints (``.json``, ``.csv``:
:func:`robocli.io.waypoints.read_waypoints`) and robot model files
(:func:`robocli.kinematics.model.parse_model`).

The option byte picks the reader and the file's suffix; the rest is the file. Reading must
return or raise a :class:`robocli.errors.RobocliError`; anything else is a finding.
"""

from __future__ import annotations

import io
import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
from harness import scratch

from robocli.errors import RobocliError
from robocli.io.waypoints import read_waypoints
from robocli.kinematics.model import parse_model
from robocli.kinematics.trajlog import TrajectoryLog, read_log, write_log

#: (reader, suffix) by the option byte's low bits.
READERS: tuple[tuple[str, str], ...] = (
    ("log", ".json"),
    ("log", ".csv"),
    ("log", ".npz"),
    ("waypoints", ".json"),
    ("waypoints", ".csv"),
    ("model", ".json"),
)


def _path(suffix: str) -> Path:
    return scratch("files") / f"input{suffix}"


def fuzz_files(data: bytes) -> None:
    """Option byte (reader, suffix), then the file's bytes."""
    if not data:
        return
    reader, suffix = READERS[data[0] % len(READERS)]
    content = data[1:]
    try:
        if reader == "model":
            parse_model(content, "fuzz model")
            return
        path = _path(suffix)
        path.write_bytes(content)
        if reader == "log":
            read_log(path)
        else:
            read_waypoints(path)
    except RobocliError:
        pass


def seed_inputs() -> list[bytes]:
    """Valid files of each reader: logs written by :func:`write_log` in every format, the
    waypoint layouts of the docs, the shipped robot models."""
    out = []
    t = np.linspace(0.0, 1.0, 5)
    q = np.outer(t, [0.1, -0.2, 0.3, 0.0, 0.5, -0.6])
    log = TrajectoryLog.from_positions(t, q, tcp=np.outer(t, [0.3, 0.0, 0.5]))
    for index, (reader, suffix) in enumerate(READERS):
        if reader == "log":
            path = _path(suffix)
            write_log(log, path, overwrite=True)  # one scratch file, written again per input
            out.append(bytes((index,)) + path.read_bytes())
    waypoints = [
        {"joints": q.tolist(), "time": t.tolist()},
        {"joints_deg": np.degrees(q).tolist()},
        {"points": [[0.3, 0.0, 0.5], [0.35, 0.05, 0.45]]},
    ]
    for doc in waypoints:
        out.append(bytes((3,)) + json.dumps(doc).encode())
    for header, rows in (("q1,q2,q3,q4,q5,q6,time", q), ("x,y,z", [[0.3, 0.0, 0.5]] * 2)):
        buf = io.StringIO()
        buf.write(header + "\n")
        for i, row in enumerate(rows):
            values = [*row, float(t[i])] if header.endswith("time") else list(row)
            buf.write(",".join(repr(float(v)) for v in values) + "\n")
        out.append(bytes((4,)) + buf.getvalue().encode())
    models = Path(__file__).resolve().parent.parent / "robocli" / "kinematics" / "models"
    for model in sorted(models.glob("*.json")):
        out.append(bytes((5,)) + model.read_bytes())
    return out


TARGETS: dict[str, tuple[Callable[[bytes], None], tuple[str, ...]]] = {
    "file-readers": (fuzz_files, ()),
}
