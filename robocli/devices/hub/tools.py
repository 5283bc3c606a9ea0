"""What the hub commands are made of: sample rows, streaming pulls and a survey of a hub
(the recording proxy of ``dump hub`` is :mod:`robocli.analysis.ros4mat`).

Part of the hub client (:mod:`robocli.devices.hub.client`); the CLI (``robocli subscribe``,
``connect hub``) is a thin layer over these.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from robocli.devices.hub.client import Hub, Reading
from robocli.devices.hub.decode import BATTERY_ROWS, COMPUTER_ROWS, GPS_ROWS
from robocli.errors import DeviceError
from robocli.protocols.ros4mat import SENSORS, MsgType, sensor_type

_COLUMNS: dict[int, tuple[str, ...]] = {
    MsgType.ADC: tuple(f"ch{i}" for i in range(8)),
    MsgType.IMU: ("ax", "ay", "az", "gx", "gy", "gz", "mx", "my", "mz"),
    MsgType.GPS: GPS_ROWS,
    MsgType.COMPUTER: COMPUTER_ROWS,
    MsgType.BATTERY: BATTERY_ROWS,
}


PULLABLE: tuple[str, ...] = tuple(
    n for n in SENSORS if n not in ("webcam", "ordinateur", "kinect_ir")
)
"""The ros4mat names of the sensors a client can pull (``kinect_ir``, 0x28, has no pull)."""


INTEGER_COLUMNS = frozenset(
    {"beams", "height", "width", "state", "n_cells", "mem_used", "mem_free", "mem_buffers"}
)
"""Columns of :func:`rows_of` whose values are integers on the wire (counts, sizes, states)."""


def columns_of(sensor: str, channels: int = 0xFF) -> tuple[str, ...]:
    """Column names of :func:`rows_of` (``t`` first). ``channels`` masks ADC channels."""
    kind = sensor_type(sensor)
    if kind == MsgType.ADC:
        return ("t", *(c for i, c in enumerate(_COLUMNS[kind]) if channels >> i & 1))
    if kind in _COLUMNS:
        return ("t", *_COLUMNS[kind])
    if kind == MsgType.HOKUYO:
        return ("t", "beams", "min", "max", "mean")
    return ("t", "height", "width", "mean")


def rows_of(reading: Reading, channels: int = 0xFF) -> np.ndarray[Any, Any]:
    """One row per sample (samples x columns, float64): the reading's time, then its fields
    (fixed-record sensors) or a summary of the scan / image (laser, cameras)."""
    n = len(reading)
    kind = sensor_type(reading.sensor)
    if kind in _COLUMNS:
        data = reading.data
        if kind == MsgType.ADC:
            data = data[[i for i in range(8) if channels >> i & 1]]
        return np.column_stack([reading.t, np.asarray(data, dtype=np.float64).T])
    if kind == MsgType.HOKUYO:
        r = reading.data
        if not n:
            return np.empty((0, 5))
        stats = [np.full(n, r.shape[0]), r.min(axis=0), r.max(axis=0), r.mean(axis=0)]
        return np.column_stack([reading.t, *stats])
    d = reading.data
    if not n:
        return np.empty((0, 4))
    means = d.reshape(-1, n).mean(axis=0)
    return np.column_stack([reading.t, np.full(n, d.shape[0]), np.full(n, d.shape[1]), means])


def stream(
    hub: Hub,
    sensor: str,
    poll: float,
    *,
    duration: float | None = None,
    count: int | None = None,
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], Any] = time.sleep,
) -> Iterator[Reading]:
    """Pull ``sensor`` ``poll`` times a second and yield each non-empty reading, until
    ``duration`` seconds passed or ``count`` samples came (the last reading is cut to
    ``count``). Pulls keep a fixed schedule (no drift), skipping missed slots."""
    period = 1.0 / poll
    start = clock()
    due = start
    got = 0
    while True:
        reading = hub.read(sensor)
        if count is not None and got + len(reading) > count:
            reading = _head(reading, count - got)
        got += len(reading)
        if len(reading):
            yield reading
        now = clock()
        if (count is not None and got >= count) or (
            duration is not None and now - start >= duration
        ):
            return
        due += period
        if due < now:
            due = now + period - (now - due) % period
        wait = due - now
        if duration is not None:
            wait = min(wait, start + duration - now)
        if wait > 0:
            sleep(wait)


def _head(reading: Reading, n: int) -> Reading:
    cut = {k: v[..., :n] for k, v in reading.fields.items()}
    return Reading(
        reading.sensor, reading.data[..., :n], reading.t[:n], reading.hub_t[:n],
        reading.packet_timestamp, reading.info, cut, reading.nbytes, reading.lost,
    )  # fmt: skip


def survey(hub: Hub, window: float = 0.5, sensors: tuple[str, ...] | None = None) -> dict[str, Any]:
    """What a client can learn about a hub over ros4mat alone: for each sensor, whether a
    silent subscribe is accepted (someone runs it) and, over ``window`` seconds, its sample
    rate and latest time; the round trip and clock offset. ros4mat has no message listing
    sensors or clients: the client id the hub assigned (max existing + 1) bounds the number
    of clients it has seen."""
    names = sensors or PULLABLE
    active: dict[str, Any] = {}
    for name in names:
        try:
            hub.subscribe(name)
        except DeviceError as exc:
            active[name] = {"active": False, "reason": str(exc).split(": ", 1)[-1]}
        else:
            active[name] = {"active": True}
    running = [n for n, v in active.items() if v["active"]]
    first = {n: hub.read(n) for n in running}
    start = time.monotonic()
    time.sleep(window)
    for name in running:
        reading = hub.read(name)
        span = time.monotonic() - start
        before = first[name]
        latest = reading.hub_t[-1] if len(reading) else before.hub_t[-1] if len(before) else None
        active[name].update(
            rate_hz=round(len(reading) / span, 1),
            samples_per_pull=len(reading),
            latest_hub_time=None if latest is None else float(latest),
        )
    for name in running:
        with contextlib.suppress(DeviceError):
            hub.unsubscribe(name)
    return {
        "hub": hub.url,
        "protocol_version": 3,
        "client_id": hub.client_id,
        "clients_seen": hub.client_id,
        "compression": hub.compress,
        "rtt_ms": None if hub.sync.rtt is None else round(hub.sync.rtt * 1e3, 3),
        "clock_offset_ms": None if hub.sync.offset is None else round(hub.sync.offset * 1e3, 3),
        "sensors": active,
    }


__all__ = [
    "INTEGER_COLUMNS",
    "PULLABLE",
    "columns_of",
    "rows_of",
    "stream",
    "survey",
]
