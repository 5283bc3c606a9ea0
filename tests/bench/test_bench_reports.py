"""robocli.bench.reports as a script calls it, against the built-in simulators."""

from __future__ import annotations

import pytest

from robocli.bench import reports
from robocli.errors import InvalidArgument


def test_laser_jitter_reports_the_scan_period() -> None:
    report = reports.jitter("laser", n=12)
    names = [row["name"] for row in report.results]
    assert "scan period (received)" in names and not report.interrupted
    assert report.hist["period"].size > 0 and report.paper is None


def test_sip_reports_the_client_work() -> None:
    report = reports.sip(n=12)
    assert report.results[0]["name"] == "client CPU per SIP" and "work" in report.hist


def test_an_unknown_target_is_refused() -> None:
    with pytest.raises(InvalidArgument):
        reports.jitter("toaster", n=10)
