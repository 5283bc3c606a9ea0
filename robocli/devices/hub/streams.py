"""A hub sensor's samples as ``robocli subscribe`` streams them, for a script too:
subscribed, pulled on a fixed schedule, as rows of numbers (:func:`sample_rows`), with
the samples the hub's buffer lost said as they happen (:class:`LossReport`), and as JSON
Lines data in SI units (:func:`json_rows`).

>>> from robocli.devices.hub.client import Hub                           # doctest: +SKIP
>>> from robocli.devices.hub.streams import json_rows, sample_rows
>>> with Hub.connect("sim://") as hub:
...     for batch in sample_rows(hub, "imu", 100, count=10):
...         print(json_rows(batch.columns, batch.rows))
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from robocli.devices.hub.tools import INTEGER_COLUMNS, columns_of, rows_of, stream

if TYPE_CHECKING:
    import numpy as np

    from robocli.devices.hub.client import Hub

__all__ = ["LOSS_REPORT_S", "TO_SI", "PulledRows", "LossReport", "json_rows", "sample_rows"]

LOSS_REPORT_S = 10.0  #: while streaming, samples lost are said at most this often
#: JSON is SI: the IMU's g, deg/s and uT (as the hub sends them; the table and CSV keep
#: them) become m/s^2, rad/s and T, as in recordings and exports.
TO_SI = {
    **dict.fromkeys(("ax", "ay", "az"), 9.80665),
    **dict.fromkeys(("gx", "gy", "gz"), math.pi / 180),
    **dict.fromkeys(("mx", "my", "mz"), 1e-6),
}


class LossReport:
    """When to say that samples were lost (the client counts them, ``hub.lost``): when it
    first happens, then at most every :data:`LOSS_REPORT_S`, and the total at the end.
    :meth:`update` returns the sentence to say, or None."""

    def __init__(self, sensor: str, buffer: int) -> None:
        self.sensor, self.buffer = sensor, buffer
        self.said, self.said_at = 0, -LOSS_REPORT_S

    def update(self, lost: int, final: bool = False) -> str | None:
        now = time.monotonic()
        if final:  # the total, even when the last "so far" gave the same number
            if not lost:
                return None
        elif lost <= self.said or now - self.said_at < LOSS_REPORT_S:
            return None
        self.said, self.said_at = lost, now
        return (
            f"{lost} {self.sensor} samples lost{'' if final else ' so far'} (gaps in "
            f"their times): the hub's buffer of {self.buffer} overflowed between pulls; raise "
            "--buffer or pull more often (--poll)"
        )


@dataclass(frozen=True)
class PulledRows:
    """One pull's samples: ``rows`` (time, then ``columns[1:]``, as the hub sends them) and,
    when it is time to say it, the :class:`LossReport` sentence (``lost``)."""

    columns: tuple[str, ...]
    rows: np.ndarray[Any, Any]
    lost: str | None = None


def sample_rows(hub: Hub, sensor: str, rate: int, *, buffer: int | None = None,
                poll: int | None = None, channels: int = 0xFF, duration: float | None = None,
                count: int | None = None) -> Iterator[PulledRows]:  # fmt: skip
    """Subscribe ``hub`` to ``sensor`` at ``rate`` Hz (the hub keeping ``buffer`` samples,
    default 1 s; ``poll`` pulls a second, default rate/4 + 10 and at most ``rate``;
    ``channels``: the ADC's mask) and yield each pull's samples until ``duration`` s or
    ``count`` samples. The first batch, once subscribed, has no rows; so may the last,
    which says the loss total."""
    import numpy as np

    from robocli.protocols.ros4mat import MsgType, adc_freq_send_default, sensor_type

    params: dict[str, Any] = {"channels": channels} if sensor_type(sensor) == MsgType.ADC else {}
    hub.subscribe(sensor, rate, buffer=buffer, poll=poll, **params)
    pulls = poll or min(float(adc_freq_send_default(rate)), float(rate))
    cols, losses = columns_of(sensor, channels), LossReport(sensor, buffer or rate)
    none = np.zeros((0, len(cols)))
    yield PulledRows(cols, none)
    for reading in stream(hub, sensor, pulls, duration=duration, count=count):
        yield PulledRows(
            cols, rows_of(reading, channels), losses.update(hub.lost.get(sensor.lower(), 0))
        )
    last = losses.update(hub.lost.get(sensor.lower(), 0), final=True)
    if last is not None:
        yield PulledRows(cols, none, last)


def _json_value(value: float, integer: bool) -> float | int | None:
    """A field as JSON has it: an integer field as an int, a float32 one at its 7 digits,
    NaN (no reading, e.g. no CPU temperature sensor) as null (JSON has no NaN)."""
    if not math.isfinite(value):
        return None
    return int(value) if integer else float(f"{value:.7g}")


def json_rows(columns: tuple[str, ...], rows: np.ndarray[Any, Any]) -> str:
    """``rows`` as JSON Lines, one object per sample, in SI units (:data:`TO_SI`), at the
    precision of the wire (float32 fields, microsecond times)."""
    ints = [c in INTEGER_COLUMNS for c in columns[1:]]
    scale = [TO_SI.get(c, 1.0) for c in columns[1:]]
    lines = []
    for row in rows.tolist():
        si = [v * k for v, k in zip(row[1:], scale, strict=True)]
        values = [round(row[0], 6), *map(_json_value, si, ints)]
        lines.append(json.dumps(dict(zip(columns, values, strict=True))) + "\n")
    return "".join(lines)
