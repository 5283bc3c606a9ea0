"""`robocli bench` as a user runs it: in a subprocess, stopped by Ctrl-C (SIGINT) or SIGTERM,
it prints what it collected and exits 130; `--json` stays machine-readable."""

from __future__ import annotations

import json
import os
import signal
import subprocess

import pytest

from tests.commands.helpers import ROBOCLI
from tests.commands.test_screens import terminal

pytestmark = pytest.mark.skipif(os.name != "posix", reason="POSIX signals")


def _interrupt(args: tuple[str, ...], stage: str, sig: int = signal.SIGINT) -> tuple[int, str, str]:
    """Run ``robocli ARGS`` with stderr on a terminal; once its progress bar names ``stage``
    (a stage shows one after about 2 s, with samples collected), send ``sig``. Returns the
    exit code, stdout and what the terminal showed."""
    with terminal(*args, stderr_on_pty=True) as term:
        term.read_until(stage.encode(), timeout=120)
        assert term.proc.poll() is None, term.text
        term.proc.send_signal(sig)
        # "within a second" is the aim; this bound only keeps a broken build from hanging CI
        code, out = term.finish(60)
    return code, out, term.text


def _counts(out: str) -> dict[str, int]:
    """measurement name -> n, from the text table (name, unit, n, seven statistics)."""
    rows = {}
    for line in out.splitlines():
        parts = line.rsplit(None, 9)
        if len(parts) == 10 and parts[2].isdigit():
            rows[parts[0].strip()] = int(parts[2])
    return rows


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_stops_the_c_floor_and_prints_what_it_collected(sig: int) -> None:
    code, out, err = _interrupt(("bench", "rtt", "-n", "1000000"), "C floor, same CPU", sig)
    assert code == 130, err
    rows = _counts(out)
    assert 0 < rows["C floor, same CPU"] < 1_000_000
    assert "interrupted" in err


def test_ctrl_c_stops_the_client_stage_and_prints_what_it_collected() -> None:
    args = ("bench", "rtt", "-n", "1000000", "--floor-n", "200")
    code, out, err = _interrupt(args, "C responder")
    assert code == 130, err
    rows = _counts(out)
    assert rows["C floor, same CPU"] == 200
    # the stage running at the signal (a bare socket, then the client, against the
    # responder) reports what it collected
    partial = [n for name, n in rows.items() if "C responder" in name]
    assert partial and 0 < partial[-1] < 1_000_000
    assert "x floor (median)" in out


def test_ctrl_c_stops_jitter_with_partial_periods() -> None:
    code, out, err = _interrupt(("bench", "jitter", "-n", "1000"), "SIPs")
    assert code == 130, err
    assert 0 < _counts(out)["SIP period"] < 1000


def test_rtt_json_names_every_stage_with_floor_multiples() -> None:
    proc = subprocess.Popen([*ROBOCLI, "bench", "rtt", "-n", "50", "--json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    try:
        out, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        pytest.fail(f"bench rtt -n 50 did not finish in 60 s: {err[-500:]}")
    assert proc.returncode == 0, err
    results = {r["name"]: r for r in json.loads(out)}
    assert {"C floor, same CPU", "client vs C responder", "client vs simulator process"} <= set(
        results
    )
    for name in ("client vs C responder", "client vs simulator process"):
        r = results[name]
        assert r["n"] == 50 and r["x_floor_median"] > 0 and isinstance(r["target_met"], bool)
        assert "CPU" in r["where"] or "unpinned" in r["where"]
