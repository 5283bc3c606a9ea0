"""``robocli bench``: one unit per measurement, named, in the table and its histogram;
JSON without float noise (issue 7: 16)."""

from __future__ import annotations

import json
import re

from cli.helpers import run


def test_jitter_table_and_histogram_in_ms() -> None:
    proc = run("bench", "jitter", "-n", "12")
    assert proc.returncode == 0, proc.stderr
    row = next(line for line in proc.stdout.splitlines() if line.startswith("SIP period"))
    name, unit, n, mean, median, *_ = re.split(r"\s{2,}", row)
    assert unit == "ms" and int(n) == 12 and 90 < float(median) < 110
    assert "histogram: period (ms)" in proc.stdout
    bins = [line for line in proc.stdout.splitlines() if " - " in line]
    assert bins and all(" ms " in line for line in bins)
    assert all(90 < float(line.split()[0]) < 110 for line in bins)


def test_keepalive_period_in_ms_and_json_rounded() -> None:
    proc = run("bench", "sip", "-n", "12")
    assert proc.returncode == 0, proc.stderr
    row = next(line for line in proc.stdout.splitlines() if line.startswith("keep-alive"))
    assert re.match(r"keep-alive period\s+ms\s+\d+\s+4\d\d\.\d ", row), row
    data = json.loads(run("bench", "sip", "-n", "12", "--json").stdout)
    for result in data:
        assert result["unit"] == "us"
        for key in ("mean", "median", "p99"):
            assert len(repr(result[key]).split(".")[-1]) <= 3, result
