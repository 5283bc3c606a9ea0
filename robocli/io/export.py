"""Exporting a recording (``robocli export``): one file per channel, or the IRB120 paper's
JSON log of an arm.

>>> from robocli.io.export import export, arm_log        # doctest: +SKIP
>>> export("run.mcap", "csv", "out/")                     # out/hub_imu.csv, out/pioneer_pose.csv...
>>> arm_log("arm.mcap")                                   # a TrajectoryLog, as validate reads

**Per channel** (``csv``, ``jsonl``, ``npz``): every decoded channel (JSON messages; the raw
bytes channels are for ``dump --file`` and are left out) becomes ``TOPIC.SUFFIX``, the topic's
slashes turned into underscores (``/hub/imu`` -> ``hub_imu.csv``). Each message gets ``t``,
its acquisition time (the MCAP publish time), and ``log_time``, its host receive time, both
in Unix-epoch seconds: the time base of every ``--json`` output. ``jsonl``: the message as
recorded, ``t`` and ``log_time`` added. ``csv``: nested fields flattened with dots and list
items with their index (``linear_acceleration.x``, ``channels.0``), the columns those of the
channel's first message (a later message's extra fields are left out, its missing ones
empty). ``npz``: one array per flattened field (numbers as float64, NaN where a message has
none; text as strings), lists of numbers as one 2-D array per field (rows padded with NaN).
Image data stays the base64 text it is in the recording.

**irb120-json**: the arm's joint states (``JOINT_FEEDBACK`` when the controller sent it,
with its velocities, else ``JOINT_POSITION``, velocities by finite differences) as a
:class:`~robocli.kinematics.trajlog.TrajectoryLog`: time from 0 at the first sample, on the
controller's clock when it sent one (JOINT_FEEDBACK's time; a sample that does not advance
it is kept once), else on the publish times; the first sample's Unix time as
``time_origin``, and the flange position from the recording's ``tcp`` channel when it
covers every sample. NPZ and irb120-json are built in memory.

A recording killed before its end exports up to its last complete record.
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

from robocli.errors import InvalidArgument, RobocliError
from robocli.output import replace_output

if TYPE_CHECKING:
    from robocli.kinematics.trajlog import TrajectoryLog

__all__ = ["FORMATS", "arm_log", "channel_messages", "export", "flatten", "read_any_log"]

FORMATS = ("csv", "jsonl", "npz", "irb120-json")
JOINT_SCHEMA = "robocli.JointState"


def channel_messages(path: str | Path) -> Iterator[tuple[str, str, int, int, dict[str, Any]]]:
    """``(topic, schema, publish_ns, log_ns, message)`` of every decoded message of the
    recording at ``path``, in file order (a channel's messages in the order written): the
    JSON of a robocli recording, or the CDR of a ROS 2 bag read as
    :func:`robocli.ros2.read.decode` reads it (its schema: the robocli one it is read as,
    :func:`~robocli.ros2.read.view_schema`). Raw channels are left out."""
    from mcap.records import Channel, Message, Schema

    from robocli.io.record.links import is_raw
    from robocli.io.record.reader import iter_messages

    schemas: dict[int, str] = {}
    channels: dict[int, tuple[str, str, str]] = {}
    for record in iter_messages(path):
        if isinstance(record, Schema):
            schemas[record.id] = record.name
        elif isinstance(record, Channel):
            schema = schemas.get(record.schema_id, "")
            encoding = record.message_encoding
            if encoding in ("json", "cdr") and not is_raw(encoding, schema):
                channels[record.id] = (record.topic, schema, encoding)
        elif isinstance(record, Message) and record.channel_id in channels:
            topic, schema, encoding = channels[record.channel_id]
            kind, message = message_of(path, topic, schema, encoding, record.data)
            yield topic, kind, record.publish_time, record.log_time, message


def message_of(path: str | Path, topic: str, schema: str, encoding: str, data: bytes,
               view: bool = False) -> tuple[str, dict[str, Any]]:  # fmt: skip
    """(schema, message as a dict) of one message of a ``json`` or ``cdr`` channel (see
    :func:`channel_messages`; ``view``: a CDR message with the fields robocli's figures
    read, :func:`robocli.ros2.read.decode`). Raises :class:`RobocliError` for one that does
    not decode."""
    if encoding == "cdr":
        from robocli.ros2.read import decode, view_schema

        try:
            return view_schema(schema), decode(schema, data, view)
        except RobocliError as exc:
            raise RobocliError(f"{path}: a message of {topic}: {exc}") from None
    try:
        message = json.loads(data)
    except (ValueError, UnicodeDecodeError, RecursionError):
        raise RobocliError(f"{path}: a message of {topic} is not JSON") from None
    return schema, message if isinstance(message, dict) else {"value": message}


def export(path: str | Path, fmt: str, out_dir: str | Path | None = None,
           overwrite: bool = False) -> list[Path]:  # fmt: skip
    """Export the recording at ``path`` as ``fmt`` (one of :data:`FORMATS`) into ``out_dir``
    (default: the recording's folder); returns the files written, in topic order. Each file
    is written beside its name and put in place once every one is written (a failure leaves
    the folder as it was); an existing one is refused unless ``overwrite``, a symbolic link
    always (:class:`~robocli.output.OutputError`, before any file is put in place)."""
    if fmt not in FORMATS:
        raise InvalidArgument(f"format must be one of {', '.join(FORMATS)}, not {fmt!r}")
    src = Path(path)
    out = Path(out_dir) if out_dir is not None else src.parent
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RobocliError(f"cannot create {out}: {exc.strerror or exc}") from None
    if fmt == "irb120-json":
        return _export_arm(src, out, overwrite)
    writers: dict[str, _Writer] = {}
    with contextlib.ExitStack() as files:  # each file put in place as the stack closes
        for topic, _schema, publish, log, message in channel_messages(src):
            writer = writers.get(topic)
            if writer is None:
                path = out / f"{_file_stem(topic)}.{fmt}"
                stream = files.enter_context(replace_output(path, overwrite, text=fmt != "npz"))
                writer = writers[topic] = _Writer(path, fmt, stream)
            writer.add(publish, log, message)
        if not writers:
            raise RobocliError(f"{src}: no decoded channel to export")
        for writer in writers.values():
            writer.close()
    return [writers[topic].path for topic in sorted(writers)]


def _file_stem(topic: str) -> str:
    stem = topic.strip("/").replace("/", "_")
    return "".join(c if c.isalnum() or c in "._-" else "_" for c in stem) or "channel"


class _Writer:
    """One channel's file: streamed for csv/jsonl, gathered then written for npz (into
    ``stream``, a :func:`~robocli.output.replace_output`'s)."""

    def __init__(self, path: Path, fmt: str, stream: IO[Any]) -> None:
        self.path, self.fmt = path, fmt
        self._fh: IO[Any] = stream
        self._csv: Any = None
        self._columns: dict[str, list[Any]] = {}  # npz: each field's values so far
        self._rows = 0

    def add(self, publish_ns: int, log_ns: int, message: dict[str, Any]) -> None:
        times = {"t": publish_ns / 1e9, "log_time": log_ns / 1e9}
        try:
            if self.fmt == "jsonl":
                assert self._fh is not None
                row = {**times, **message, **times}  # t first, and ours
                self._fh.write(json.dumps(row, separators=(",", ":")) + "\n")
                return
            row = {**times, **flatten(message, lists=self.fmt != "npz"), **times}
            if self.fmt == "npz":
                self._column_add(row)
                return
            if self._csv is None:
                self._csv = csv.DictWriter(self._fh, fieldnames=list(row), extrasaction="ignore")
                self._csv.writeheader()
            self._csv.writerow(row)
        except OSError as exc:
            raise RobocliError(f"cannot write {self.path}: {exc.strerror or exc}") from None

    def _column_add(self, row: dict[str, Any]) -> None:
        columns, n = self._columns, self._rows
        for key, value in row.items():
            column = columns.get(key)
            if column is None:
                column = columns[key] = [None] * n
            column.append(value)
        self._rows = n = n + 1
        if len(row) < len(columns):
            for column in columns.values():
                if len(column) < n:
                    column.append(None)

    def close(self) -> None:
        """Write what is gathered (npz); the stream itself is closed by its owner."""
        if self.fmt != "npz":
            return
        import numpy as np

        arrays = {key: _column(values) for key, values in self._columns.items()}
        try:
            np.savez_compressed(self._fh, **arrays)
        except OSError as exc:
            raise RobocliError(f"cannot write {self.path}: {exc.strerror or exc}") from None


def flatten(message: dict[str, Any], prefix: str = "", lists: bool = True) -> dict[str, Any]:
    """Nested dicts as dotted keys; lists of dicts by index; lists of numbers by index when
    ``lists`` (else kept whole)."""
    out: dict[str, Any] = {}
    for key, value in message.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(flatten(value, f"{name}.", lists))
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            for i, item in enumerate(value):
                out.update(flatten(item, f"{name}.{i}.", lists))
        elif isinstance(value, list) and lists:
            for i, item in enumerate(value):
                out[f"{name}.{i}"] = item
        else:
            out[name] = value
    return out


def _column(values: list[Any]) -> Any:
    """One npz array of a field's values (None: absent)."""
    import numpy as np

    present = [v for v in values if v is not None]
    if present and all(isinstance(v, (int, float)) for v in present):
        return np.array([math.nan if v is None else float(v) for v in values], dtype=np.float64)
    if present and all(isinstance(v, list) and all(x is None or isinstance(x, (int, float))
                                                   for x in v) for v in present):  # fmt: skip
        width = max(len(v) for v in present)
        out = np.full((len(values), width), math.nan)
        for i, v in enumerate(values):
            if v:
                out[i, : len(v)] = [math.nan if x is None else x for x in v]
        return out
    return np.array(["" if v is None else str(v) for v in values], dtype=np.str_)


# ------------------------------------------------------------------ arm (irb120-json)


def arm_log(path: str | Path, link: str | None = None) -> TrajectoryLog:
    """The joint states of the arm recorded at ``path`` (the first arm link, or ``link``)
    as a :class:`~robocli.kinematics.trajlog.TrajectoryLog` (see the module docstring). Raises
    :class:`RobocliError` when the recording holds no arm joint states."""
    import numpy as np

    from robocli.kinematics.trajlog import TrajectoryLog, finite_difference

    joints: dict[str, list[tuple[int, dict[str, Any]]]] = {}
    tcp: dict[str, dict[int, list[float | None]]] = {}
    for topic, schema, publish, _log, message in channel_messages(path):
        name, _, kind = topic.strip("/").rpartition("/")
        if link is not None and name != link:
            continue
        if schema == JOINT_SCHEMA and kind in ("joint_states", "joint_feedback"):
            joints.setdefault(f"{name}/{kind}", []).append((publish, message))
        elif kind == "tcp" and isinstance(message.get("pose"), dict):
            p = message["pose"].get("position", {})
            xyz: list[Any] = [p.get(k) for k in "xyz"] if isinstance(p, dict) else [None]
            tcp.setdefault(name, {})[publish] = xyz if all(map(_finite, xyz)) else [None]
    arms = list(dict.fromkeys(key.rpartition("/")[0] for key in joints))
    if not arms:
        where = f" of link {link!r}" if link else ""
        raise RobocliError(f"{path}: no arm joint states{where} in the recording")
    arm = arms[0]
    feedback = joints.get(f"{arm}/joint_feedback", [])
    samples = feedback if len(feedback) >= 2 else joints.get(f"{arm}/joint_states", feedback)
    clock = [s[1].get("robot_time") for s in samples]
    robot = all(_finite(c) for c in clock)
    # the controller's clock when it sent one (JOINT_FEEDBACK), else the publish time;
    # a sample that does not advance the clock (sent twice) is kept once
    keyed = sorted(((float(c) if robot and c is not None else p / 1e9, p, m) for c, (p, m) in
                    zip(clock, samples, strict=True)), key=lambda k: k[0])  # fmt: skip
    kept = [k for i, k in enumerate(keyed) if i == 0 or k[0] > keyed[i - 1][0]]
    if len(kept) < 2:
        raise RobocliError(f"{path}: {len(kept)} joint state of {arm}: too few for a log")
    stamps = [k[1] for k in kept]
    try:
        q = np.array([k[2]["position"] for k in kept], dtype=np.float64)
        velocity = [k[2].get("velocity") or [] for k in kept]
        if q.ndim != 2 or not all(isinstance(v, list) for v in velocity):
            raise ValueError("not one list of positions per sample")
    except (KeyError, TypeError, ValueError, OverflowError):
        raise RobocliError(f"{path}: malformed joint states of {arm}") from None
    t = np.array([k[0] - kept[0][0] for k in kept], dtype=np.float64)
    if all(len(v) == q.shape[1] and all(map(_finite, v)) for v in velocity):
        qd = np.array(velocity, dtype=np.float64)
    else:
        qd = finite_difference(t, q)
    poses = tcp.get(arm, {})
    xyz = [poses.get(s) for s in stamps]
    tcp_arr = None
    if all(p is not None and None not in p for p in xyz):
        tcp_arr = np.array(xyz, dtype=np.float64)
    return TrajectoryLog(t, q, qd, tcp_arr, origin=stamps[0] / 1e9)


def _finite(value: Any) -> bool:
    """Whether a JSON value is a finite number (an integer past a float's range is not)."""
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def read_any_log(path: str | Path) -> TrajectoryLog:
    """A trajectory log from a log file (:func:`~robocli.kinematics.trajlog.read_log`: .json,
    .csv, .npz) or an arm's MCAP recording (:func:`arm_log`), by suffix."""
    from robocli.kinematics.trajlog import read_log

    return arm_log(path) if Path(path).suffix.lower() == ".mcap" else read_log(path)


def _export_arm(src: Path, out: Path, overwrite: bool) -> list[Path]:
    from robocli.kinematics.trajlog import write_log
    from robocli.output import check_output

    path = check_output(out / f"{src.stem}.json", overwrite)  # before reading the recording
    return [write_log(arm_log(src), path, overwrite)]
