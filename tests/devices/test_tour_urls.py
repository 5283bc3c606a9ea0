"""examples/tour.py, the README's Python example, runs unchanged in its own process against
the four places a Pioneer can be, with only the URL changed: ``sim://`` (in the script's
process), ``tcp://`` and a pty (a PioneerSim here), and ``zenoh/NAME`` (a PioneerSim behind
a bridge, through a loopback Zenoh router with scouting off). Each run exits 0 and moves
the robot: the simulator's true pose where it runs here, the script's odometry for sim://.
The simulators run 4x faster than real time; the subprocess timeout only bounds a failure."""

from __future__ import annotations

import contextlib
import math
import os
import re
import socket
import subprocess
import sys
import threading
from collections.abc import Iterator

import pytest

import robocli
from robocli.errors import InvalidArgument
from robocli.sim.pioneer.server import PioneerSim
from tests.paths import EXAMPLES

SCRIPT = EXAMPLES / "tour.py"
DEADLINE_S = 120.0  # bounds a failure only: the suite runs with the CPU oversubscribed
DROVE = re.compile(r"drove from x=(\S+) y=(\S+) to x=(\S+) y=(\S+) th=\S+$", re.MULTILINE)


def _run_tour(url: str) -> float:
    """Run the script on ``url``; the distance it says it drove (m, its odometry)."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    done = subprocess.run([sys.executable, str(SCRIPT), url], capture_output=True, text=True,
                          timeout=DEADLINE_S, env=env)  # fmt: skip
    assert done.returncode == 0, f"{url}: exit {done.returncode}: {done.stderr[-2000:]}"
    assert done.stderr == "", done.stderr
    drove = DROVE.search(done.stdout)
    assert drove, done.stdout
    x0, y0, x, y = map(float, drove.groups())
    return math.dist((x0, y0), (x, y))


def _free_endpoint() -> str:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{s.getsockname()[1]}"


@contextlib.contextmanager
def _behind_zenoh(simulator: PioneerSim) -> Iterator[str]:
    """The simulator behind a PioneerBridge named ``tour``, a client of a loopback router
    (scouting off); yields the script's URL, the router's endpoint in its query."""
    pytest.importorskip("zenoh", reason="needs robocli-robots[zenoh] (eclipse-zenoh)")
    from robocli.bridge.pioneer import PioneerBridge
    from robocli.zenoh.router import start_router
    from robocli.zenoh.session import close_session, open_session

    endpoint = _free_endpoint()
    with start_router(endpoint) as router, \
            robocli.Pioneer.connect(simulator.serve_tcp("127.0.0.1", 0)) as robot:  # fmt: skip
        assert router.listen == [endpoint]
        session = open_session(endpoint, "client")
        bridge = PioneerBridge(robot, session, "tour")
        try:
            yield f"zenoh/tour?zenoh={endpoint}"
        finally:
            bridge.close()
            close_session(session)


@contextlib.contextmanager
def _where(kind: str, simulator: PioneerSim) -> Iterator[str]:
    if kind == "tcp":
        yield simulator.serve_tcp("127.0.0.1", 0)
    elif kind == "pty":
        yield simulator.serve_pty()
    else:
        with _behind_zenoh(simulator) as url:
            yield url


def test_the_tour_drives_the_in_process_simulator() -> None:
    assert _run_tour("sim://p3dx?time_scale=4") >= 0.25


@pytest.mark.parametrize("kind", ["tcp", "pty", "zenoh"])
def test_the_tour_runs_unchanged_with_only_the_url_changed(kind: str) -> None:
    with PioneerSim("p3dx", time_scale=4.0) as simulator:
        start = simulator.snapshot()
        with _where(kind, simulator) as url:
            assert _run_tour(url) >= 0.25
        truth = simulator.snapshot()
    assert math.dist((start.x, start.y), (truth.x, truth.y)) >= 0.2  # the robot itself moved


def test_a_zenoh_url_names_its_endpoint_once_and_refuses_what_a_bridge_owns() -> None:
    """Checked before anything is opened: no router is needed."""
    url = "zenoh/tour?zenoh=tcp/127.0.0.1:1"
    with pytest.raises(InvalidArgument, match="give the Zenoh endpoint once"):
        robocli.Pioneer.connect(url, zenoh="tcp/127.0.0.1:2")
    with pytest.raises(InvalidArgument, match=r"subtype=, baudrate= cannot be given"):
        robocli.Pioneer.connect(url, subtype="p3at", baudrate=38400)
    with pytest.raises(InvalidArgument, match="port= cannot be given"):
        robocli.Hub.connect("zenoh/lab", port=1500)
    with pytest.raises(InvalidArgument, match="zenoh= is for a zenoh/NAME URL"):
        robocli.Pioneer.connect("tcp://127.0.0.1:1", zenoh="tcp/127.0.0.1:7447")


def test_hub_connect_with_a_zenoh_url_gives_the_zenoh_hub() -> None:
    """Hub.connect("zenoh/NAME?zenoh=ENDPOINT"): the hub's Zenoh front-end, read like any hub."""
    pytest.importorskip("zenoh", reason="needs robocli-robots[zenoh] (eclipse-zenoh)")
    from robocli.hub_server.frontends.zenoh import ZenohFrontend
    from robocli.zenoh.session import close_session, open_session

    endpoint = _free_endpoint()
    server = robocli.HubServer(port=0, sim=True).start()
    session = open_session(endpoint, "server")
    front = ZenohFrontend(server.hub, session, "lab", publish={"adc": {}}).start()
    got = threading.Event()
    try:
        with robocli.Hub.connect(f"zenoh/lab?zenoh={endpoint}",
                                 listeners=[lambda *_frame: got.set()]) as hub:  # fmt: skip
            assert isinstance(hub, robocli.ZenohHub) and hub.url == "zenoh/lab"
            hub.subscribe("adc", rate=50)
            assert got.wait(DEADLINE_S), "no batch reached the listener given to connect"
    finally:
        front.close()
        close_session(session)
        server.close()
