"""Trajectory logs in the IRB120 paper's JSON layout, also as CSV and NPZ (chosen by suffix).

JSON: ``{"time": [...], "joints_positions": [[q1..qn]...], "joints_velocities": [[...]...],
"tcp": [[x, y, z]...]}`` in s, rad, rad/s and m, for simulated and measured runs alike.
CSV: a header ``time,q1..qn,qd1..qdn,x,y,z`` then one row per sample. NPZ: the same four
arrays under the JSON keys. Files are size-capped and checked; a malformed file raises
:class:`LogFormatError` with one line that names the file and the fault.
"""

from __future__ import annotations

import csv
import io
import json
import math
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from robocli.errors import EXIT_USAGE, RobocliError

FloatArray = npt.NDArray[np.float64]

MAX_LOG_BYTES = 256 * 1024 * 1024
MAX_JOINTS = 12
SUFFIXES = (".json", ".csv", ".npz")
KEYS = ("time", "joints_positions", "joints_velocities", "tcp")


class LogFormatError(RobocliError, ValueError):
    """A trajectory log that cannot be read: wrong suffix, too big, malformed, NaN, ragged."""

    exit_code = EXIT_USAGE


def open_capped(src: Path, limit: int, what: str) -> io.StringIO:
    """The text of ``src`` (UTF-8, a leading byte-order mark as Excel writes it dropped),
    read in bounded memory: a file over ``limit`` bytes, even one whose size ``stat`` cannot
    tell (a pipe, ``/dev/zero``), is refused."""
    with src.open("rb") as fh:
        data = fh.read(limit + 1)
    if len(data) > limit:
        raise LogFormatError(f"{src}: over the {limit // 2**20} MiB limit of {what}")
    return io.StringIO(data.decode("utf-8-sig"))


@dataclass(frozen=True)
class TrajectoryLog:
    """Samples of a joint trajectory: ``time`` (N,) s, ``positions`` (N, n) rad,
    ``velocities`` (N, n) rad/s and ``tcp`` (N, 3) m (``None`` when not recorded).

    ``time`` starts at 0 at the first point for generated runs and for recordings
    (:meth:`robocli.devices.arm.JointRecorder.log`); a log may also be on any other clock, as
    validation aligns clocks itself. ``origin``: where the recording clock (the controller's,
    or this computer's ``time.monotonic()``) stood at ``time`` 0, when known (kept as
    ``"time_origin"`` in JSON and NPZ; CSV has no place for it).
    """

    time: FloatArray
    positions: FloatArray
    velocities: FloatArray
    tcp: FloatArray | None = None
    origin: float | None = None

    def __post_init__(self) -> None:
        _check(self, "log")

    def __len__(self) -> int:
        return int(self.time.shape[0])

    @property
    def n_joints(self) -> int:
        """Number of joints per sample."""
        return int(self.positions.shape[1])

    @classmethod
    def from_positions(
        cls, time: npt.ArrayLike, positions: npt.ArrayLike, tcp: npt.ArrayLike | None = None
    ) -> TrajectoryLog:
        """A log whose velocities are finite differences of the positions (second order)."""
        t = np.asarray(time, dtype=float)
        q = np.asarray(positions, dtype=float)
        return cls(t, q, finite_difference(t, q), None if tcp is None else np.asarray(tcp, float))

    def to_dict(self) -> dict[str, Any]:
        """The JSON layout as plain lists."""
        out: dict[str, Any] = {
            "time": self.time.tolist(),
            "joints_positions": self.positions.tolist(),
            "joints_velocities": self.velocities.tolist(),
        }
        if self.tcp is not None:
            out["tcp"] = self.tcp.tolist()
        if self.origin is not None:
            out["time_origin"] = self.origin
        return out


def finite_difference(time: FloatArray, positions: FloatArray) -> FloatArray:
    """Joint velocities by finite differences: central inside, one-sided at the ends."""
    if time.shape[0] < 2:
        return np.zeros_like(positions)
    with np.errstate(all="ignore"):  # a bad time axis is reported by the log's own check
        return np.asarray(np.gradient(positions, time, axis=0, edge_order=1), dtype=float)


def check_writable(path: str | Path, overwrite: bool = False) -> Path:
    """Raise :class:`LogFormatError` for an unknown suffix, and
    :class:`~robocli.output.OutputError` unless a log could be written to ``path`` (see
    :func:`~robocli.output.check_output`: an existing file only with ``overwrite``, never
    a symbolic link). For commands that record for a while (or move a robot) before they
    write: check first."""
    from robocli.output import check_output

    out = Path(path)
    _suffix(out)
    return check_output(out, overwrite)


def write_log(log: TrajectoryLog, path: str | Path, overwrite: bool = False) -> Path:
    """Write ``log`` to ``path`` in the format of its suffix; returns the path. The file
    appears whole or not at all; an existing one is replaced only with ``overwrite``
    (:class:`~robocli.output.OutputError` otherwise, as for a symbolic link)."""
    from robocli.output import replace_output

    out = Path(path)
    suffix = _suffix(out)
    with replace_output(out, overwrite, text=suffix != ".npz") as fh:
        if suffix == ".npz":
            arrays = {
                "time": log.time,
                "joints_positions": log.positions,
                "joints_velocities": log.velocities,
            }
            if log.tcp is not None:
                arrays["tcp"] = log.tcp
            if log.origin is not None:
                arrays["time_origin"] = np.float64(log.origin)
            np.savez_compressed(fh, **arrays)  # type: ignore[arg-type]
        elif suffix == ".csv":
            _write_csv(log, fh)
        else:
            _write_json(log, fh)
    return out


def _write_json(log: TrajectoryLog, fh: io.TextIOBase | Any) -> None:
    """Stream the JSON one row at a time (no whole-document string in memory)."""

    def rows(name: str, arr: FloatArray, last: bool) -> None:
        fh.write(f'  "{name}": [')
        for i, row in enumerate(arr):
            fh.write(("\n    " if i == 0 else ",\n    ") + json.dumps(row.tolist()))
        fh.write("\n  ]" + ("\n" if last else ",\n"))

    fh.write('{\n  "time": ' + json.dumps(log.time.tolist()) + ",\n")
    rows("joints_positions", log.positions, False)
    rows("joints_velocities", log.velocities, log.tcp is None and log.origin is None)
    if log.tcp is not None:
        rows("tcp", log.tcp, log.origin is None)
    if log.origin is not None:
        fh.write(f'  "time_origin": {json.dumps(log.origin)}\n')
    fh.write("}\n")


def _write_csv(log: TrajectoryLog, fh: Any) -> None:
    n = log.n_joints
    writer = csv.writer(fh)
    header = ["time"] + [f"q{i + 1}" for i in range(n)] + [f"qd{i + 1}" for i in range(n)]
    if log.tcp is not None:
        header += ["x", "y", "z"]
    writer.writerow(header)
    parts = [log.time[:, None], log.positions, log.velocities]
    if log.tcp is not None:
        parts.append(log.tcp)
    for row in np.hstack(parts):
        writer.writerow([repr(float(v)) for v in row])


def read_log(path: str | Path) -> TrajectoryLog:
    """Read a log written by :func:`write_log` (or by hand in the same layout)."""
    src = Path(path)
    suffix = _suffix(src)
    try:
        size = src.stat().st_size
        if size > MAX_LOG_BYTES:
            raise LogFormatError(
                f"{src}: {size} bytes is over the {MAX_LOG_BYTES // (1024 * 1024)} MiB log limit"
            )
        if suffix == ".npz":
            return _read_npz(src)
        fh = open_capped(src, MAX_LOG_BYTES, "a log")
        return _read_csv(src, fh) if suffix == ".csv" else _read_json(src, fh)
    except OSError as exc:
        raise LogFormatError(f"{src}: cannot read ({exc.strerror})") from exc
    except UnicodeDecodeError as exc:
        raise LogFormatError(f"{src}: not UTF-8 text") from exc
    except (csv.Error, zlib.error) as exc:  # a bare CR in a CSV field, a corrupt NPZ member
        raise LogFormatError(f"{src}: not a valid {suffix[1:].upper()} log ({exc})") from None


def _suffix(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise LogFormatError(
            f"{path}: unknown log suffix {suffix or '(none)'!r}; use {', '.join(SUFFIXES)}"
        )
    return suffix


def _reject_constant(token: str) -> float:
    raise LogFormatError(f"holds {token}: logs hold finite numbers only")


def _read_json(src: Path, fh: Any) -> TrajectoryLog:
    try:
        doc = json.load(fh, parse_constant=_reject_constant)
    except LogFormatError as exc:
        raise LogFormatError(f"{src}: {exc}") from None
    except ValueError as exc:
        raise LogFormatError(f"{src}: not valid JSON ({exc})") from None
    except RecursionError:
        raise LogFormatError(f"{src}: not a log (JSON nested too deeply)") from None
    if not isinstance(doc, dict):
        raise LogFormatError(f"{src}: a log is a JSON object with keys {', '.join(KEYS)}")
    for key in ("time", "joints_positions"):
        if key not in doc:
            raise LogFormatError(f"{src}: missing key {key!r}")
    time = _array(src, "time", doc["time"], 1)
    q = _array(src, "joints_positions", doc["joints_positions"], 2)
    qd = (
        _array(src, "joints_velocities", doc["joints_velocities"], 2)
        if doc.get("joints_velocities") is not None
        else None
    )
    tcp = _array(src, "tcp", doc["tcp"], 2) if doc.get("tcp") is not None else None
    return _build(src, time, q, qd, tcp, _origin(src, doc.get("time_origin")))


def _origin(src: Path, value: Any) -> float | None:
    """The optional ``time_origin``: one finite number."""
    if value is None:
        return None
    try:
        origin = float(value)
    except (TypeError, ValueError):
        raise LogFormatError(f"{src}: 'time_origin' must be one number") from None
    if not math.isfinite(origin) or isinstance(value, bool):
        raise LogFormatError(f"{src}: 'time_origin' must be one finite number")
    return origin


def _array(src: Path, key: str, value: Any, ndim: int) -> FloatArray:
    if not isinstance(value, list):
        raise LogFormatError(f"{src}: {key!r} must be a list")
    if ndim == 2:
        width = len(value[0]) if value and isinstance(value[0], list) else None
        for i, row in enumerate(value):
            if not isinstance(row, list):
                raise LogFormatError(f"{src}: {key!r} row {i} is not a list")
            if len(row) != width:
                raise LogFormatError(
                    f"{src}: {key!r} row {i} has {len(row)} values, expected {width} (ragged rows)"
                )
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise LogFormatError(f"{src}: {key!r} holds something that is not a number") from None
    if ndim == 2 and arr.ndim == 1 and arr.shape[0] == 0:
        arr = arr.reshape(0, 0)
    return arr


def _read_csv(src: Path, fh: Any) -> TrajectoryLog:
    reader = csv.reader(fh)
    header = next(reader, None)
    if not header or header[0].strip() != "time":
        raise LogFormatError(f"{src}: a CSV log starts with a header 'time,q1,...'")
    names = [h.strip() for h in header]
    qcols = [i for i, h in enumerate(names) if h.startswith("q") and h[1:].isdigit()]
    dcols = [i for i, h in enumerate(names) if h.startswith("qd") and h[2:].isdigit()]
    tcols = [names.index(c) for c in ("x", "y", "z") if c in names]
    if not qcols or len(tcols) not in (0, 3) or (dcols and len(dcols) != len(qcols)):
        raise LogFormatError(f"{src}: CSV header needs time, q1..qn, optional qd1..qn and x,y,z")
    rows = []
    for lineno, row in enumerate(reader, start=2):
        if not row:
            continue
        if len(row) != len(names):
            raise LogFormatError(
                f"{src}: line {lineno} has {len(row)} values, expected {len(names)} (ragged rows)"
            )
        try:
            rows.append([float(v) for v in row])
        except ValueError:
            raise LogFormatError(
                f"{src}: line {lineno} holds something that is not a number"
            ) from None
    data = np.asarray(rows, dtype=float).reshape(len(rows), len(names))
    return _build(
        src,
        data[:, 0],
        data[:, qcols],
        data[:, dcols] if dcols else None,
        data[:, tcols] if tcols else None,
    )


def _read_npz(src: Path) -> TrajectoryLog:
    """An NPZ log, its members checked before any is decompressed: each one's uncompressed
    size (a deflated zip member may expand a thousandfold), and each array's header (real
    numbers only, a shape its member can hold)."""
    try:
        with zipfile.ZipFile(src) as zf:
            _check_npz_members(src, zf)
        with np.load(src, allow_pickle=False) as npz:
            missing = [k for k in ("time", "joints_positions") if k not in npz.files]
            if missing:
                raise LogFormatError(f"{src}: missing array {missing[0]!r}")
            arrays = {k: np.asarray(npz[k], dtype=float) for k in KEYS if k in npz.files}
            origin = npz["time_origin"] if "time_origin" in npz.files else None
    except (zipfile.BadZipFile, zipfile.LargeZipFile, ValueError, EOFError,
            NotImplementedError, RuntimeError) as exc:  # fmt: skip
        if isinstance(exc, LogFormatError):
            raise
        raise LogFormatError(f"{src}: not a valid NPZ log ({exc})") from None
    if origin is not None and origin.shape not in ((), (1,)):
        raise LogFormatError(f"{src}: 'time_origin' must be one number")
    return _build(
        src,
        arrays["time"],
        arrays["joints_positions"],
        arrays.get("joints_velocities"),
        arrays.get("tcp"),
        _origin(src, None if origin is None else origin.reshape(-1)[0].item()),
    )


def _check_npz_members(src: Path, zf: zipfile.ZipFile) -> None:
    total = 0
    for info in zf.infolist():
        total += info.file_size
        if info.file_size > MAX_LOG_BYTES or total > MAX_LOG_BYTES:
            raise LogFormatError(
                f"{src}: {info.filename} expands to {info.file_size} bytes, over the "
                f"{MAX_LOG_BYTES // 2**20} MiB log limit")  # fmt: skip
    for name in (*KEYS, "time_origin"):
        try:
            info = zf.getinfo(name + ".npy")
        except KeyError:
            continue
        with zf.open(info) as fh:
            version = np.lib.format.read_magic(fh)
            if version == (1, 0):
                shape, _, dtype = np.lib.format.read_array_header_1_0(fh)
            elif version == (2, 0):
                shape, _, dtype = np.lib.format.read_array_header_2_0(fh)
            else:
                raise LogFormatError(f"{src}: {name!r} has an unsupported .npy version")
        if dtype.kind not in "fiu":
            kind = {"c": "complex numbers", "b": "booleans", "O": "Python objects",
                    "U": "text", "S": "bytes"}.get(dtype.kind, f"{dtype} values")  # fmt: skip
            raise LogFormatError(f"{src}: {name!r} holds {kind}: logs hold real numbers")
        if math.prod(shape) * dtype.itemsize > info.file_size:
            raise LogFormatError(f"{src}: {name!r} is truncated (its header says {shape})")


def _build(
    src: Path,
    time: FloatArray,
    q: FloatArray,
    qd: FloatArray | None,
    tcp: FloatArray | None,
    origin: float | None = None,
) -> TrajectoryLog:
    where = str(src)
    if q.ndim != 2 or time.ndim != 1:
        raise LogFormatError(f"{where}: 'time' is a list and 'joints_positions' a list of rows")
    if qd is None and q.shape[0] == time.shape[0]:
        qd = finite_difference(time, q)
    try:
        return TrajectoryLog(time, q, qd if qd is not None else q, tcp, origin)
    except LogFormatError as exc:
        raise LogFormatError(f"{where}: {exc}") from None


def _check(log: TrajectoryLog, where: str) -> None:
    n = log.time.shape[0]
    if log.time.ndim != 1 or n == 0:
        raise LogFormatError("'time' must hold at least one sample")
    if log.positions.ndim != 2 or not 1 <= log.positions.shape[1] <= MAX_JOINTS:
        raise LogFormatError(f"'joints_positions' rows must hold 1 to {MAX_JOINTS} joints")
    named = {"joints_positions": log.positions, "joints_velocities": log.velocities}
    if log.tcp is not None:
        named["tcp"] = log.tcp
    for key, arr in named.items():
        if arr.shape[0] != n:
            raise LogFormatError(f"{key!r} has {arr.shape[0]} samples but 'time' has {n}")
    if log.velocities.shape != log.positions.shape:
        raise LogFormatError("'joints_velocities' rows must match 'joints_positions' rows")
    if log.tcp is not None and (log.tcp.ndim != 2 or log.tcp.shape[1] != 3):
        raise LogFormatError("'tcp' rows must be [x, y, z]")
    if np.all(np.isfinite(log.time)):
        steps = np.diff(log.time)
        if np.any(steps <= 0):
            bad = int(np.argmax(steps <= 0)) + 1
            raise LogFormatError(f"'time' does not increase at sample {bad}")
    for key, arr in {"time": log.time, **named}.items():
        finite = np.isfinite(arr)
        if not np.all(finite):
            bad = int(np.argmax(~finite.reshape(n, -1).all(axis=1)))
            raise LogFormatError(f"{key!r} sample {bad} holds a NaN or an infinity")
    del where  # messages are prefixed with the file by the readers


def log_summary(log: TrajectoryLog) -> dict[str, float]:
    """Duration (s), samples, and the largest joint speed (rad/s), for reports."""
    return {
        "samples": float(len(log)),
        "duration_s": float(log.time[-1] - log.time[0]),
        "max_speed_rad_s": float(np.max(np.abs(log.velocities))) if len(log) else math.nan,
    }
