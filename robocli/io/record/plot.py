"""Figures of a recording (``robocli plot``; matplotlib, the ``plot`` extra).

>>> from robocli.io.record.plot import plot                 # doctest: +SKIP
>>> plot("run.mcap", "path.png", ["/pioneer/pose", "/pioneer/laser"])
>>> plot("run.mcap", "joints.png", ["/arm/joint_feedback"])
>>> plot("run.mcap", "imu.png", ["/hub/imu"], fields=["linear_acceleration.z"])

What is drawn follows each channel's schema:

- ``foxglove.PoseInFrame`` (a Pioneer's ``pose``): the path in the plane of its frame
  (``odom``), x against y, start and end marked; with ``foxglove.LaserScan`` channels
  (``sonar``, ``laser``) every return put into that frame by the latest pose at or before the
  scan (the scan's own pose in the robot frame included): the walls the robot saw.
- ``robocli.JointState`` (an arm's ``joint_states``, ``joint_feedback``): each joint's
  position (degrees) against time.
- any other channel with ``fields``: each numeric field (dotted path, list items by index:
  ``linear_acceleration.z``, ``position.0``; a list of numbers draws one line per item)
  against time, one panel per channel.

Time, for time series, is each message's publish time: the source's own acquisition time
on the host clock (a hub sample's time, the arm controller's clock) or, where the source
gives none, the receive time; in seconds from the first message drawn. A path follows the
receive (log) times, by which poses and scans meet.
The file is read record by record (a recording cut short by a kill plots up to its last
complete chunk). :func:`plot` returns what it drew (:class:`PlotResult`), so that a
program or a test can check the figure without looking at pixels.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from robocli.errors import InvalidArgument
from robocli.io.record.mcapfile import BadRecording

__all__ = ["PlotResult", "numeric_fields", "plot"]

PATH_SCHEMAS = ("foxglove.PoseInFrame",)
SCAN_SCHEMAS = ("foxglove.LaserScan",)
JOINT_SCHEMAS = ("robocli.JointState",)
#: Scan returns drawn at most (scans are thinned evenly past it): a figure stays readable.
MAX_SCAN_POINTS = 200_000


@dataclass
class PlotResult:
    """What :func:`plot` drew into :attr:`path`: ``kind`` is ``path`` or ``time``;
    ``series`` maps each line's label to its number of points; ``scan_points`` counts the
    scan returns drawn (path plots)."""

    path: Path
    kind: str
    series: dict[str, int] = field(default_factory=dict)
    scan_points: int = 0
    duration_s: float = 0.0
    #: distinct times per line of a time series (fewer than its points: samples drawn at
    #: one time)
    distinct_times: dict[str, int] = field(default_factory=dict)
    #: (x min, x max, y min, y max) of the scan returns drawn, m; None without any
    scan_extent: tuple[float, float, float, float] | None = None

    @property
    def points(self) -> int:
        return sum(self.series.values())

    def as_dict(self) -> dict[str, Any]:
        return {"path": str(self.path), "kind": self.kind, "series": self.series,
                "points": self.points, "scan_points": self.scan_points,
                "duration_s": self.duration_s, "scan_extent": self.scan_extent,
                "distinct_times": self.distinct_times}  # fmt: skip


def _pyplot() -> Any:
    from robocli.kinematics.plot import PlotUnavailableError

    try:
        import matplotlib  # type: ignore[import-not-found,unused-ignore]  # optional extra
    except ImportError:
        raise PlotUnavailableError(
            "plotting needs matplotlib: pip install 'robocli-robots[plot]'"
        ) from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # type: ignore[import-not-found,unused-ignore]

    return plt


Messages = dict[str, list[tuple[int, Any]]]
Records = dict[str, list[tuple[int, int, Any]]]


def _read(recording: str | Path, topics: Sequence[str]) -> tuple[dict[str, str], Records]:
    """(schema name by topic for every channel of the file, (log ns, publish ns, JSON) by
    wanted topic)."""
    from mcap.records import Channel, Message, Schema

    from robocli.io.export import message_of
    from robocli.io.record.reader import iter_messages
    from robocli.ros2.read import view_schema

    schemas: dict[int, str] = {}
    channels: dict[int, tuple[str, str]] = {}
    names: dict[str, str] = {}
    types: dict[str, str] = {}  # the schema each topic is written with
    out: Records = {t: [] for t in topics}
    for record in iter_messages(recording):
        if isinstance(record, Message):
            topic, encoding = channels.get(record.channel_id, ("", ""))
            wanted = out.get(topic)
            if wanted is not None and encoding in ("json", "cdr"):
                wanted.append((record.log_time, record.publish_time, message_of(
                    recording, topic, types[topic], encoding, record.data, True)[1]))  # fmt: skip
        elif isinstance(record, Schema):
            schemas[record.id] = record.name
        elif isinstance(record, Channel):
            channels[record.id] = (record.topic, record.message_encoding)
            types[record.topic] = schemas.get(record.schema_id, "")
            names[record.topic] = (view_schema(types[record.topic])
                                   if record.message_encoding == "cdr"
                                   else types[record.topic])  # fmt: skip
    return names, out


def numeric_fields(message: Any, prefix: str = "") -> list[str]:
    """The dotted paths of the numeric leaves of a JSON message (a list of numbers is one
    path): what ``--field`` can name."""
    if isinstance(message, dict):
        out: list[str] = []
        for key, value in message.items():
            out += numeric_fields(value, f"{prefix}{key}.")
        return out
    if _is_number(message) or (isinstance(message, list) and message
                               and all(_is_number(v) for v in message)):  # fmt: skip
        return [prefix.rstrip(".")]
    return []


def _is_number(v: Any) -> bool:
    """A JSON number a float can hold (an integer past its range is not)."""
    if not isinstance(v, (int, float)) or isinstance(v, bool):
        return False
    return isinstance(v, float) or -(2**1023) < v < 2**1023


#: The largest coordinate drawn (m): past it, matplotlib's axis limits overflow.
_FAR = 1e15


def _finite(v: Any) -> bool:
    return _is_number(v) and math.isfinite(v) and abs(v) < _FAR


def _fits(schema: str, msg: Any) -> bool:
    """Whether a message has the fields, of the types, that the figure of ``schema`` reads:
    a pose's position and orientation, a scan's angles and ranges, joint names and
    positions."""
    if not isinstance(msg, dict):
        return False
    if schema in PATH_SCHEMAS or schema in SCAN_SCHEMAS:
        pose = msg.get("pose") or {}
        p, q = (pose.get("position") or {}, pose.get("orientation")) \
            if isinstance(pose, dict) else (None, None)  # fmt: skip
        if not isinstance(p, dict) or not all(_finite(p.get(k, 0.0)) for k in "xy"):
            return False
        if q and not (isinstance(q, dict) and all(_finite(q.get(k)) for k in "xyzw")):
            return False
    if schema in SCAN_SCHEMAS:
        ranges = msg.get("ranges") or []
        return (
            isinstance(ranges, list)
            and all(r is None or _is_number(r) for r in ranges)
            and _finite(msg.get("start_angle"))
            and _finite(msg.get("end_angle"))
        )
    if schema in JOINT_SCHEMAS:
        names, position = msg.get("name", []), msg.get("position") or []
        return (
            isinstance(names, list)
            and isinstance(position, list)
            and all(v is None or _finite(v) for v in position)
        )
    return True


def _get(message: Any, path: str) -> Any:
    value = message
    for part in path.split("."):
        if isinstance(value, dict) and part in value:
            value = value[part]
        elif isinstance(value, list) and part.isdigit() and int(part) < len(value):
            value = value[int(part)]
        else:
            return None
    return value


def plot(recording: str | Path, output: str | Path, channels: Sequence[str],
         fields: Iterable[str] = (), *, title: str | None = None,
         overwrite: bool = False) -> PlotResult:  # fmt: skip
    """Draw ``channels`` of ``recording`` into the PNG ``output`` (see the module docstring).
    Raises :class:`InvalidArgument` for a channel the file does not have, a channel that
    cannot be drawn without ``fields``, a field that is not numeric, or pose channels mixed
    with time series; :class:`~robocli.kinematics.plot.PlotUnavailableError` without
    matplotlib; :class:`~robocli.output.OutputError` for an ``output`` that exists
    (without ``overwrite``) or is a symbolic link, before reading."""
    from robocli.output import check_output

    topics = list(dict.fromkeys(channels))
    fields = list(fields)
    if not topics:
        raise InvalidArgument("name at least one channel to plot")
    if Path(output).suffix.lower() != ".png":  # matplotlib would pick a format by it
        raise InvalidArgument(f"{output}: a plot is written as PNG; give a name ending in .png")
    check_output(output, overwrite)
    plt = _pyplot()
    schemas, records = _read(recording, topics)
    missing = [t for t in topics if t not in schemas]
    if missing:
        known = ", ".join(t for t, s in schemas.items() if s) or "none"
        raise InvalidArgument(f"{recording} has no channel {', '.join(missing)} (channels: "
                              f"{known})")  # fmt: skip
    for topic in topics:
        if not all(_fits(schemas[topic], m) for _, _, m in records[topic]):
            raise BadRecording(f"{recording}: a {topic} message does not fit its schema "
                               f"{schemas[topic]}")  # fmt: skip
    paths = [t for t in topics if schemas[t] in PATH_SCHEMAS]
    scans = [t for t in topics if schemas[t] in SCAN_SCHEMAS]
    series = [t for t in topics if t not in paths and (t not in scans or not paths)]
    if paths and series:
        raise InvalidArgument("plot a path (pose and scan channels) or time series, not both")
    # a path follows the receive times (poses and scans meet by them); a time series the
    # sources' own acquisition times (a hub reply's samples share one receive time)
    data: Messages = {
        t: [(log, m) for log, _, m in records[t]] if paths else
        sorted(((pub, m) for _, pub, m in records[t]), key=lambda item: item[0])
        for t in topics
    }  # fmt: skip
    firsts = [msgs[0][0] for msgs in data.values() if msgs]
    t0 = min(firsts) if firsts else 0
    last = max((msgs[-1][0] for msgs in data.values() if msgs), default=t0)
    result = PlotResult(Path(output), "path" if paths else "time", duration_s=(last - t0) / 1e9)
    if paths:
        fig = _plot_path(plt, result, data, paths, scans)
    else:
        fig = _plot_series(plt, result, data, schemas, series, fields, t0)
    if title:
        fig.suptitle(title)
    from robocli.kinematics.plot import save_png

    try:
        save_png(fig, result.path, overwrite)
    finally:
        plt.close(fig)
    return result


def _yaw(q: dict[str, float]) -> float:
    return math.atan2(2 * (q["w"] * q["z"] + q["x"] * q["y"]),
                      1 - 2 * (q["y"] ** 2 + q["z"] ** 2))  # fmt: skip


def _pose2d(msg: Any) -> tuple[float, float, float]:
    pose = msg.get("pose") or {}
    p, q = pose.get("position") or {}, pose.get("orientation")
    return (float(p.get("x", 0.0)), float(p.get("y", 0.0)), _yaw(q) if q else 0.0)


def _plot_path(plt: Any, result: PlotResult, data: dict[str, list[tuple[int, Any]]],
               paths: list[str], scans: list[str]) -> Any:  # fmt: skip
    fig, ax = plt.subplots(figsize=(7.5, 7.0))
    tracks: dict[str, list[tuple[int, tuple[float, float, float]]]] = {}
    for topic in paths:
        track = tracks[topic] = sorted(((t, _pose2d(m)) for t, m in data[topic]),
                                       key=lambda item: item[0])  # fmt: skip
        xs, ys = [p[0] for _, p in track], [p[1] for _, p in track]
        ax.plot(xs, ys, "-", lw=1.8, label=f"{topic} ({len(track)} poses)")
        if track:
            ax.plot(xs[:1], ys[:1], "o", color="green")
            ax.plot(xs[-1:], ys[-1:], "s", color="red")
        result.series[topic] = len(track)
    total = sum(len(m.get("ranges", ())) for topic in scans for _, m in data[topic])
    every = max(1, math.ceil(total / MAX_SCAN_POINTS))
    for topic in scans:
        # the scans of /NAME/... go with the pose of the same /NAME/, else the first pose
        source = topic.split("/")[1] if topic.startswith("/") else ""
        poses = next((tracks[p] for p in paths if p.split("/")[1:2] == [source]),
                     tracks[paths[0]])  # fmt: skip
        times = [t for t, _ in poses]
        xs, ys = [], []
        for k, (t, msg) in enumerate(data[topic]):
            i = bisect.bisect_right(times, t) - 1
            if i < 0 or k % every:
                continue
            rx, ry, rth = poses[i][1]
            sx, sy, sth = _pose2d(msg)
            ranges = msg.get("ranges") or []
            n = len(ranges)
            start, end = float(msg["start_angle"]), float(msg["end_angle"])
            step = (end - start) / (n - 1) if n > 1 else 0.0
            c, s = math.cos(rth), math.sin(rth)
            for j, r in enumerate(ranges):
                if r is None or not 0 < r < math.inf:
                    continue  # no return
                a = sth + start + j * step
                px, py = sx + r * math.cos(a), sy + r * math.sin(a)
                x, y = rx + c * px - s * py, ry + s * px + c * py
                if abs(x) < _FAR and abs(y) < _FAR:  # a range of 1e308 is none
                    xs.append(x)
                    ys.append(y)
        ax.plot(xs, ys, ".", ms=1.5, alpha=0.5, label=f"{topic} ({len(xs)} returns)")
        result.scan_points += len(xs)
        if xs:
            box = (min(xs), max(xs), min(ys), max(ys))
            old = result.scan_extent or box
            result.scan_extent = (min(old[0], box[0]), max(old[1], box[1]),
                                  min(old[2], box[2]), max(old[3], box[3]))  # fmt: skip
    frame = next((m.get("frame_id") for t in paths for _, m in data[t][:1]), None)
    ax.set_xlabel(f"x (m){f', frame {frame}' if frame else ''}")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title("path (o start, \u25a1 end)")
    fig.tight_layout()
    return fig


def _plot_series(plt: Any, result: PlotResult, data: dict[str, list[tuple[int, Any]]],
                 schemas: dict[str, str], topics: list[str], fields: list[str],
                 t0: int) -> Any:  # fmt: skip
    fig, axes = plt.subplots(len(topics), 1, sharex=True, squeeze=False,
                             figsize=(9.0, 2.0 + 2.6 * len(topics)))  # fmt: skip
    for ax, topic in zip(axes[:, 0], topics, strict=True):
        msgs = data[topic]
        times = [(t - t0) / 1e9 for t, _ in msgs]
        if not msgs:
            raise InvalidArgument(f"{topic} has no messages to plot")
        if not fields and schemas[topic] in JOINT_SCHEMAS:
            names = msgs[0][1].get("name", []) if msgs else []
            for j, name in enumerate(names):
                ys = [math.degrees(p[j]) if j < len(p := m.get("position") or []) and p[j] is
                      not None else math.nan for _, m in msgs]  # fmt: skip
                ax.plot(times, ys, lw=1.2, label=name)
                result.series[f"{topic} {name}"] = len(ys)
                result.distinct_times[f"{topic} {name}"] = len(set(times))
            ax.set_ylabel("position (deg)")
        else:
            mine = [f for f in fields if any(_get(m, f) is not None for _, m in msgs[:50])]
            if not mine:
                found = [f for f in numeric_fields(msgs[0][1]) if not f.startswith("timestamp")] \
                    if msgs else []  # fmt: skip
                raise InvalidArgument(f"{topic} ({schemas[topic] or 'no schema'}): name the "
                                      "fields to plot with --field (numeric fields: "
                                      f"{', '.join(found) or 'none'})")  # fmt: skip
            for name in mine:
                _field(ax, result, topic, name, msgs, times)
        ax.set_title(topic, fontsize=9, loc="left")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize=7)
    unused = [f for f in fields if not any(k.startswith(f"{t} {f}") for t in topics
                                           for k in result.series)]  # fmt: skip
    if unused:
        raise InvalidArgument(f"no channel given has the field {', '.join(unused)}")
    axes[-1, 0].set_xlabel("time (s) from the first message")
    fig.tight_layout()
    return fig


def _field(ax: Any, result: PlotResult, topic: str, name: str, msgs: list[tuple[int, Any]],
           times: list[float]) -> None:  # fmt: skip
    values = [_get(m, name) for _, m in msgs]
    sample = next((v for v in values if v is not None), None)
    if isinstance(sample, list):
        width = max(len(v) for v in values if isinstance(v, list))
        for k in range(width):
            ys = [float(v[k]) if isinstance(v, list) and k < len(v) and _is_number(v[k])
                  else math.nan for v in values]  # fmt: skip
            ax.plot(times, ys, lw=1.0, label=f"{name}[{k}]")
            result.series[f"{topic} {name}[{k}]"] = len(ys)
            result.distinct_times[f"{topic} {name}[{k}]"] = len(set(times))
        return
    if not _is_number(sample):
        found = [f for f in numeric_fields(msgs[0][1]) if not f.startswith("timestamp")] \
            if msgs else []  # fmt: skip
        raise InvalidArgument(f"{topic} has no numeric field {name!r} (numeric fields: "
                              f"{', '.join(found) or 'none'})")  # fmt: skip
    ys = [float(v) if _is_number(v) else math.nan for v in values]
    ax.plot(times, ys, lw=1.0, label=name)
    result.series[f"{topic} {name}"] = len(ys)
    result.distinct_times[f"{topic} {name}"] = len(set(times))
