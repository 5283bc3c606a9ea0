"""Hub sources from a Pioneer: the built-in ARCOS simulator behind the Pioneer client."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from robocli.hub_server import HubServer
from robocli.sim.pioneer.server import PioneerSim


@pytest.fixture
def pioneer_url() -> Iterator[str]:
    with PioneerSim() as sim:
        yield sim.serve_tcp("127.0.0.1", 0)


def test_pioneer_battery_and_analog_through_the_hub(pioneer_url: str, raw: Any, wait: Any) -> None:
    with HubServer(port=0, sim=False, pioneer=pioneer_url) as srv:
        assert {"battery", "adc", "sysinfo"} == set(srv.sensors)
        assert not srv.sensors["battery"]["simulated"]
        c = raw(srv.port)
        c.connect()
        assert (
            c.subscribe("battery", {"freq_acquisition": 10, "freq_send": 10}, buffer=50).error == 0
        )
        assert (
            c.subscribe("adc", {"freq_acquisition": 10, "freq_send": 10, "channels": 255}).error
            == 0
        )
        got: list[dict[str, Any]] = []
        wait(lambda: got.extend(c.pull("battery").body or []) or len(got) >= 3, what="SIPs")
        volts = [r["vtotal"] for r in got]
        assert all(10.0 < v < 14.0 for v in volts)
        t = np.array([r["t"] for r in got])
        assert (np.diff(t) > 0).all() and 0.05 < np.diff(t).mean() < 0.5  # one per SIP (100 ms)
        adc = wait(lambda: c.pull("adc").body, what="an ADC record")
        assert len(adc[0]["channels"]) == 8
        c.send(bytes.fromhex("06000000000001000000040000000400000000000000000000000001000100"))
        wait(lambda: srv.sensors["adc"]["digital_out"] == [1, 0, 1, 0], what="digital outputs")
        c.close()


def test_pioneer_away_is_an_error_reply(raw: Any) -> None:
    with HubServer(port=0, sim=False, pioneer="tcp://127.0.0.1:9") as srv:
        c = raw(srv.port)
        c.connect()
        err = c.subscribe("battery", {"freq_acquisition": 10, "freq_send": 10})
        assert err.error and "battery" in err.error_text
        assert not srv.sensors["battery"]["active"]
        c.close()
