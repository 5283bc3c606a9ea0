"""Hub sources that play a recording back (``robocli serve --replay FILE.mcap``).

A hub recording (:mod:`robocli.io.record`) keeps every data reply the hub sent, byte for
byte, in its raw ``ros4mat`` rx channel. :func:`read_hub_recording` takes the samples out
of those replies, each sensor's records exactly as the hub made them (values, image and
scan bytes, JPEG or raw), with the hub's own acquisition time of each; a sample pulled by
several replies is kept once. :func:`replay_sources` turns them into hub sources, one per
recorded sensor, that the hub serves as any other (rings, any number of clients, ros4mat
clients included).

**Time.** All the sources of one recording share one :class:`ReplayTimeline`: it starts
when the first of them starts (the first subscription) and runs ``speed`` times as fast as
the recording. A sample recorded at hub time ``t`` is served once the timeline reaches it,
stamped ``origin + (t - start) / speed`` on the serving hub's clock: at speed 1 the samples
keep their recorded spacing (to the rounding of a float64 epoch time, under a microsecond),
and samples of different sensors keep their order and offsets. A sensor subscribed later
joins the timeline where it is. At the end the sources fall silent, or with ``loop`` the
timeline starts over after one more typical interval (laps follow each other, stamps keep
growing). A hub stalled for more than :data:`MAX_CATCH_UP_S` skips what it missed instead
of flooding its clients.

Subscribe parameters (rate, resolution...) are accepted and ignored: a replay serves what
was recorded, at the recorded rates.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from robocli.errors import InvalidArgument, ProtocolError, RobocliError
from robocli.hub_server.sources.base import EMPTY_T, Batch, Source

__all__ = [
    "RecordedSensor",
    "ReplaySource",
    "ReplayTimeline",
    "read_hub_recording",
    "replay_sources",
]

MAX_BATCH_HZ = 100.0  #: a replay source is polled at most this often
MAX_CATCH_UP_S = 5.0
"""A replay late by more than this (a stalled hub) skips the samples missed before it; the
rings hold 10 s, so a client that keeps pulling loses nothing to a shorter stall."""
MAX_REPLAY_BYTES = 1 << 30
"""Sample bytes a replay holds in memory at most (1 GiB: about 75 s of a 320 x 240 raw
camera at 60 Hz, hours of IMU and ADC); a larger recording is refused in one line."""


@dataclass
class RecordedSensor:
    """One sensor's recorded samples: hub acquisition times ``t`` (sorted, unique) and
    ``records`` in the hub's layout (the wire record, or ``info`` then blob fields
    ``blob0``... padded to the largest one; ``sizes`` (n, blobs) their used bytes)."""

    name: str
    t: npt.NDArray[np.float64]
    records: npt.NDArray[Any]
    blobs: tuple[str, ...] = ()
    sizes: npt.NDArray[np.int64] | None = None

    @property
    def rate(self) -> float:
        """Mean samples per second over the recording (1 for a single sample)."""
        span = float(self.t[-1] - self.t[0]) if len(self.t) > 1 else 0.0
        return (len(self.t) - 1) / span if span > 0 else 1.0

    @property
    def interval(self) -> float:
        """The median interval between samples (s), 1 s for a single sample."""
        return float(np.median(np.diff(self.t))) if len(self.t) > 1 else 1.0


class ReplayTimeline:
    """The clock the replay sources of one recording share (see the module docstring):
    recorded times ``start``..``end``, ``speed``, ``loop`` with laps of ``period``
    recorded seconds."""

    def __init__(self, start: float, end: float, speed: float = 1.0, loop: bool = False,
                 gap: float = 0.0) -> None:  # fmt: skip
        if not (math.isfinite(speed) and speed > 0):
            raise InvalidArgument(f"speed must be a positive number, not {speed!r}")
        self.start, self.end, self.speed, self.loop = start, end, speed, loop
        self.period = max(end - start + max(gap, 0.0), 1e-3)
        self.origin: float | None = None  #: hub time at which the replay began
        self._lock = threading.Lock()

    def begin(self, now: float) -> float:
        """The hub time of the timeline's origin, set to ``now`` on the first call."""
        with self._lock:
            if self.origin is None:
                self.origin = now
            return self.origin

    def reached(self, now: float) -> float:
        """Recorded seconds since ``start`` that the timeline has reached at hub time ``now``
        (laps included)."""
        origin = self.begin(now)
        return max(0.0, now - origin) * self.speed

    def finished(self, now: float) -> bool:
        """Whether a replay without loop has played everything (False before it began)."""
        if self.origin is None or self.loop:
            return False
        return self.reached(now) > self.end - self.start


class ReplaySource(Source):
    """One recorded sensor served on a :class:`ReplayTimeline`."""

    simulated = False

    def __init__(self, recorded: RecordedSensor, timeline: ReplayTimeline) -> None:
        self.recorded = recorded
        self.timeline = timeline
        self.name = recorded.name  # type: ignore[misc]  # per instance, not per class
        self.blobs = recorded.blobs  # type: ignore[misc]
        self._rel = recorded.t - timeline.start  # recorded seconds since the timeline start
        self._lap, self._i = 0, 0
        super().__init__()

    def configure(self, params: Mapping[str, Any]) -> None:
        self.rate = self.recorded.rate * self.timeline.speed
        self.batch_rate = max(1.0, min(self.rate, MAX_BATCH_HZ))
        self.params = {"replay": "recorded", "samples": len(self.recorded.t)}

    def dtype(self) -> np.dtype[Any]:
        return self.recorded.records.dtype

    def start(self, t0: float) -> None:
        self._seek(self.timeline.reached(t0))

    def _seek(self, reached: float) -> None:
        """Put the cursor on the first sample at or after recorded time ``reached``."""
        tl = self.timeline
        lap = math.floor(reached / tl.period) if tl.loop else 0
        self._lap = lap
        self._i = int(np.searchsorted(self._rel, reached - lap * tl.period, side="left"))

    def poll(self, now: float) -> Batch:
        tl = self.timeline
        reached = tl.reached(now)
        if reached - self._position() > MAX_CATCH_UP_S * tl.speed:  # stalled: skip
            self._seek(reached - MAX_CATCH_UP_S * tl.speed)
        origin = tl.begin(now)
        n = len(self._rel)
        times: list[npt.NDArray[np.float64]] = []
        parts: list[npt.NDArray[Any]] = []
        while n:
            base = self._lap * tl.period
            end = int(np.searchsorted(self._rel, reached - base, side="right"))
            if end > self._i:
                times.append(origin + (base + self._rel[self._i : end]) / tl.speed)
                parts.append(self.recorded.records[self._i : end])
                self._i = end
            if self._i < n or not tl.loop or reached < base + tl.period:
                break
            self._lap, self._i = self._lap + 1, 0
        if not times:
            return self.empty()
        t = np.concatenate(times) if len(times) > 1 else times[0]
        records = np.concatenate(parts) if len(parts) > 1 else parts[0].copy()
        _stamp(records, t)
        return t, records

    def _position(self) -> float:
        """The recorded time (laps included) of the next sample to serve."""
        base = self._lap * self.timeline.period
        if self._i < len(self._rel):
            return base + float(self._rel[self._i])
        return base + self.timeline.period if self.timeline.loop else math.inf

    def blob_sizes(self, records: npt.NDArray[Any]) -> npt.NDArray[np.int64]:
        if not self.blobs:
            return super().blob_sizes(records)
        info = records["info"]
        if self.name == "depth":
            sizes = [info["rgb"]["size_data"], info["depth"]["size_data"]]
            return np.stack(sizes, axis=1).astype(np.int64)
        return np.asarray(info["size_data"], dtype=np.int64).reshape(len(records), len(self.blobs))

    def empty(self) -> Batch:
        return EMPTY_T, self.recorded.records[:0].copy()


def _stamp(records: npt.NDArray[Any], t: npt.NDArray[np.float64]) -> None:
    """Write the serving times into the records' own time fields."""
    names = records.dtype.names or ()
    if "t" in names:
        records["t"] = t
        return
    info = records["info"]
    if info.dtype.names and "rgb" in info.dtype.names:  # depth: both images share the time
        info["rgb"]["t"] = t
        info["depth"]["t"] = t
    elif info.ndim == 2:  # stereo: (n, 2)
        info["t"] = t[:, None]
    else:
        info["t"] = t


# ------------------------------------------------------------------------ reading


def read_hub_recording(path: str | Path, max_bytes: int = MAX_REPLAY_BYTES
                       ) -> dict[str, RecordedSensor]:  # fmt: skip
    """The samples of every sensor in the hub recording at ``path`` (see the module
    docstring), by the hub's sensor name. Raises :class:`RobocliError` when the file holds
    no hub link or no sample, or more than ``max_bytes`` of samples."""
    from robocli.io.capture import CaptureStats
    from robocli.io.record import raw_frames

    samples: dict[str, list[tuple[float, Any, list[bytes]]]] = {}
    stats = CaptureStats()
    held = 0
    for _t, direction, frame in raw_frames(path, "ros4mat", stats):
        if direction == "rx":
            held += _samples_of(frame, samples)
            if held > max_bytes:
                raise RobocliError(f"{path}: over {max_bytes / 2**20:.0f} MiB of samples to "
                                   "hold for the replay; replay a shorter recording")  # fmt: skip
    if not samples:
        raise RobocliError(f"{path}: the hub recording holds no sensor sample")
    return {name: _recorded(name, items) for name, items in sorted(samples.items())}


def _samples_of(frame: bytes, out: dict[str, list[tuple[float, Any, list[bytes]]]]) -> int:
    """Add the samples of one data reply (other replies are skipped); returns their bytes."""
    from robocli.devices.hub.decode import HEADER, body_of
    from robocli.hub_server.frontends.ros4mat import SENSOR_IDS
    from robocli.protocols.ros4mat import MsgType, record_dtype

    if len(frame) < HEADER.size:
        return 0
    header = HEADER.unpack_from(frame, 0)
    mtype, error, n = header[0], header[1], header[3]
    name = SENSOR_IDS.get(mtype)
    if error or not n or name is None:
        return 0
    try:
        _, body = body_of(frame)
    except RobocliError:
        return 0  # a reply the recording could not decode either: its raw bytes stay
    buf = bytes(body)
    dtype = record_dtype(mtype)
    items = out.setdefault(name, [])
    try:
        if mtype not in (MsgType.HOKUYO, MsgType.WEBCAM, MsgType.WEBCAM_STEREO, MsgType.KINECT):
            records = np.frombuffer(buf, dtype=dtype, count=n)
            items.append((math.nan, records, []))  # a whole reply of fixed records
            return len(buf)
        count = 2 * n if mtype == MsgType.WEBCAM_STEREO else n
        infos = np.frombuffer(buf, dtype=dtype, count=count)
    except ValueError:
        raise ProtocolError(f"hub {name} reply of {len(buf)} bytes shorter than its "
                            f"{n} records") from None  # fmt: skip
    pos = count * dtype.itemsize
    per = 2 if mtype == MsgType.WEBCAM_STEREO else 1
    for k in range(n):
        group = infos[k * per : (k + 1) * per]
        if mtype == MsgType.KINECT:
            sizes = [int(group[0]["rgb"]["size_data"]), int(group[0]["depth"]["size_data"])]
            t = float(group[0]["rgb"]["t"])
        else:
            sizes = [int(info["size_data"]) for info in group]
            t = float(group[0]["t"])
        blobs = []
        for size in sizes:
            if pos + size > len(buf):
                raise ProtocolError(f"hub {name} reply: a blob of {size} bytes past its end")
            blobs.append(buf[pos : pos + size])
            pos += size
        items.append((t, group if per > 1 else group[0], blobs))
    return len(buf)


def _recorded(name: str, items: list[tuple[float, Any, list[bytes]]]) -> RecordedSensor:
    """One sensor's samples, in time order, each time once."""
    if items and all(math.isnan(t) for t, _, _ in items):  # fixed records: whole replies
        every = np.concatenate([rec for _, rec, _ in items])
        stamps, first = np.unique(every["t"].astype(np.float64), return_index=True)
        return RecordedSensor(name, stamps, every[first])
    unique: dict[float, tuple[Any, list[bytes]]] = {}
    for t, rec, blobs in items:
        unique.setdefault(t, (rec, blobs))
    times = sorted(unique)
    stamps = np.array(times, dtype=np.float64)
    first_rec, first_blobs = unique[times[0]]
    nblobs = len(first_blobs)
    widths = [max(1, *(len(unique[x][1][b]) for x in times)) for b in range(nblobs)]
    info_shape = (2,) if name == "stereo" else ()
    fields: list[Any] = [("info", first_rec.dtype, info_shape)]
    blob_names = tuple(f"blob{b}" for b in range(nblobs))
    fields += [(blob, np.uint8, (w,)) for blob, w in zip(blob_names, widths, strict=True)]
    records = np.zeros(len(times), dtype=np.dtype(fields))
    sizes = np.zeros((len(times), nblobs), dtype=np.int64)
    for i, x in enumerate(times):
        rec, blobs = unique[x]
        records["info"][i] = rec
        for b, blob in enumerate(blobs):
            records[blob_names[b]][i, : len(blob)] = np.frombuffer(blob, dtype=np.uint8)
            sizes[i, b] = len(blob)
    return RecordedSensor(name, stamps, records, blob_names, sizes)


def replay_sources(path: str | Path, speed: float = 1.0, loop: bool = False,
                   max_bytes: int = MAX_REPLAY_BYTES) -> dict[str, Source]:  # fmt: skip
    """Hub sources (by sensor name) playing back the hub recording at ``path`` on one
    shared :class:`ReplayTimeline` (see the module docstring): give them to
    :class:`~robocli.hub_server.HubServer` as ``sources``. ``max_bytes``: see
    :data:`MAX_REPLAY_BYTES`."""
    sensors = read_hub_recording(path, max_bytes)
    start = min(float(s.t[0]) for s in sensors.values())
    end = max(float(s.t[-1]) for s in sensors.values())
    busiest = max(sensors.values(), key=lambda s: len(s.t))
    timeline = ReplayTimeline(start, end, speed, loop, gap=busiest.interval)
    return {name: ReplaySource(s, timeline) for name, s in sensors.items()}
