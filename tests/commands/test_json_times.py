"""One time base (issue 14): every ``t`` of every command's ``--json`` output is Unix time
in seconds, so that two logs of one experiment join. ``connect --json`` gave monotonic
seconds since boot and ``dump --json`` seconds since the capture began; those stay, under
their own names (``t_mono``, ``t_rel``).

Each command runs as a process against the built-in simulators; every number under a key
``t``, at any depth, must lie within a few minutes of this test's clock.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from robocli.hub_server import HubServer
from tests.commands.helpers import run

#: How far a ``t`` may lie from now (s): the command ran within the last minutes.
SLACK = 300.0


@pytest.fixture(scope="module")
def hub() -> Iterator[str]:
    with HubServer(bind="127.0.0.1", port=0, sim=True) as srv:
        yield f"127.0.0.1:{srv.port}"


def times(value: Any) -> Iterator[Any]:
    """Every value under a key ``t`` in ``value``, at any depth."""
    if isinstance(value, dict):
        for k, v in value.items():
            if k == "t":
                yield v
            yield from times(v)
    elif isinstance(value, list):
        for v in value:
            yield from times(v)


def documents(out: str) -> list[Any]:
    """One pretty JSON document, or JSON Lines."""
    text = out.strip()
    try:
        return [json.loads(text)]
    except json.JSONDecodeError:
        return [json.loads(line) for line in text.splitlines()]


def check(*args: str) -> list[Any]:
    done = run(*args, timeout=120)
    assert done.returncode == 0, done.stderr
    docs = documents(done.stdout)
    found = [t for doc in docs for t in times(doc)]
    assert found, f"no t in {done.stdout[:300]}"
    now = time.time()
    assert all(isinstance(t, float) and abs(t - now) < SLACK for t in found), found[:5]
    return docs


def test_connect_pioneer_and_arm() -> None:
    state = check("connect", "pioneer", "sim", "--once", "--json")[0]["state"]
    assert 0 < state["t_mono"] < state["t"]  # the monotonic reading kept, named
    check("connect", "arm", "sim", "--once", "--json")
    lines = check("connect", "arm", "sim", "--json", "--count", "3")
    assert len(lines) == 3 and all("t_mono" in x for x in lines)


def test_subscribe(hub: str) -> None:
    check("subscribe", "imu", "--hub", hub, "--rate", "50", "--json", "--count", "3")


def test_dump_live_and_from_files(tmp_path: Path, hub: str) -> None:
    capture = tmp_path / "p.jsonl"
    live = check("dump", "pioneer", "sim", "-n", "12", "--json", "-o", str(capture))
    again = check("dump", "pioneer", "--file", str(capture), "--json")
    assert [x["t_rel"] for x in again] == [x["t_rel"] for x in live]
    assert all(abs(a["t"] - b["t"]) < 1e-5 for a, b in zip(live, again, strict=True))
    check("dump", "arm", "sim", "-n", "5", "--json")
    recording = tmp_path / "h.mcap"
    done = run("record", "--hub", hub, "--sensors", "imu", "-n", "50", "-o", str(recording),
               timeout=120)  # fmt: skip
    assert done.returncode == 0, done.stderr
    check("dump", "hub", "--file", str(recording), "--json", "-n", "10")


def test_doctor() -> None:
    check("doctor", "--json")
