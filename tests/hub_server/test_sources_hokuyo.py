"""The hub's ``laser`` sensor from a Hokuyo (the built-in SCIP simulator behind the Laser
client), in the original ros4mat client's HOKUYO shape; and ``robocli serve --laser``."""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from robocli.hub_server import HubServer
from robocli.hub_server.sources.hokuyo import HokuyoSource
from robocli.sim.hokuyo import HokuyoSim


@pytest.fixture(params=["utm-30lx", "urg-04lx"])
def laser_sim(request: pytest.FixtureRequest) -> Iterator[HokuyoSim]:
    with HokuyoSim(str(request.param), time_scale=2.0) as sim:
        sim.serve_tcp()
        yield sim


def test_hokuyo_scans_through_the_hub(laser_sim: HokuyoSim, raw: Any, wait: Any) -> None:
    assert laser_sim.url is not None
    source = HokuyoSource(laser_sim.url)
    with HubServer(port=0, sim=False, sources={"laser": source}) as srv:
        assert not srv.sensors["laser"]["simulated"]
        c = raw(srv.port)
        c.connect()
        assert (
            c.subscribe("hokuyo", {"freq_acquisition": 40, "freq_send": 40}, buffer=40).error == 0
        )
        got: list[Any] = []

        def enough() -> bool:
            msg = c.pull("hokuyo")
            if msg.size:
                got.append(msg.body)
            return sum(len(b["infos"]) for b in got) >= 3

        wait(enough, what="3 laser scans")
        c.close()
    m = laser_sim.model
    info = got[0]["infos"][0]
    ranges = np.array(got[0]["ranges"][0], dtype=np.float64)
    assert info["size_data"] == m.steps * 4 and ranges.shape == (m.steps,)
    assert info["angle_min"] == pytest.approx(m.angles([m.amin])[0], abs=1e-6)
    assert info["angle_max"] == pytest.approx(m.angles([m.amax])[0], abs=1e-6)
    assert info["angle_increment"] == pytest.approx(2 * math.pi / m.ares, rel=1e-6)
    assert info["range_max"] == pytest.approx(m.dmax / 1000)
    wire, _ = laser_sim.scan_values()
    want = wire[m.amin : m.amax + 1] / 1000.0
    want[(wire[m.amin : m.amax + 1] < m.dmin)] = 0.0  # error codes read 0
    assert np.allclose(ranges, want, atol=1e-6)
    times = [i["t"] for b in got for i in b["infos"]]
    assert np.diff(times) == pytest.approx([m.period] * (len(times) - 1), abs=1e-3)


def test_laser_away_is_an_error_reply(raw: Any) -> None:
    with HubServer(port=0, sim=False, sources={"laser": HokuyoSource("tcp://127.0.0.1:9")}) as srv:
        c = raw(srv.port)
        c.connect()
        err = c.subscribe("hokuyo", {"freq_acquisition": 10, "freq_send": 10})
        assert err.error
        assert not srv.sensors["laser"]["active"]
        c.close()


def test_serve_sim_with_a_laser_url(laser_sim: HokuyoSim) -> None:
    from tests.commands.helpers import read_lines, running

    with running("serve", "--sim", "--port", "0", "--laser", str(laser_sim.url)) as proc:
        assert proc.stdout is not None and proc.stderr is not None
        (line,) = read_lines(proc.stdout, 1)
        assert "laser" in line and re.search(r"tcp://127\.0\.0\.1:\d+", line), line
        note = read_lines(proc.stderr, 1)
        assert note and "laser: from the Hokuyo at" in note[0]
