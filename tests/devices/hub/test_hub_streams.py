"""robocli.devices.hub.streams as a notebook user calls it, against the built-in hub
simulator over a real loopback socket."""

from __future__ import annotations

import json
import math

import numpy as np

from robocli.devices.hub.client import Hub
from robocli.devices.hub.streams import LossReport, json_rows, sample_rows


def test_sample_rows_subscribes_and_stops_at_the_count() -> None:
    with Hub.connect("sim://") as hub:
        batches = list(sample_rows(hub, "imu", 100, count=10))
    assert len(batches[0].rows) == 0  # subscribed: the columns are known
    assert sum(len(b.rows) for b in batches) == 10
    assert batches[0].columns[0] == "t" and "ax" in batches[0].columns


def test_json_rows_are_si_and_null_for_nan() -> None:
    rows = np.array([[1.5, 1.0, 2.0, float("nan")]])
    (line,) = json_rows(("t", "ax", "gx", "mx"), rows).splitlines()
    data = json.loads(line)
    assert data["ax"] == 9.80665 and math.isclose(data["gx"], 2 * math.pi / 180, rel_tol=1e-6)
    assert data["mx"] is None and data["t"] == 1.5


def test_loss_report_says_the_first_loss_then_the_total() -> None:
    report = LossReport("imu", 100)
    assert report.update(0) is None
    assert "3 imu samples lost so far" in (report.update(3) or "")
    assert report.update(4) is None  # not again within LOSS_REPORT_S
    assert "4 imu samples lost (gaps" in (report.update(4, final=True) or "")
