"""Addresses as the commands read them: one parser for every host, port and URL option,
IPv6 literals included, malformed ones refused in one line with exit 2 (issue 13: 14)."""

from __future__ import annotations

import json
import re
from collections.abc import Iterator

import pytest

from robocli.hub_server import HubServer
from robocli.sim.abb.server import AbbSim
from robocli.sim.pioneer.server import PioneerSim
from tests.commands.helpers import one_line_error, run, running
from tests.peers import ipv6_loopback, needs_ipv6


@pytest.fixture(scope="module")
def hub6() -> Iterator[int]:
    """A simulated hub listening on [::1] only; yields its port."""
    if not ipv6_loopback():
        pytest.skip("no IPv6 loopback ([::1]) here")
    with HubServer(bind="::1", port=0, sim=True) as srv:
        yield srv.port


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (("subscribe", "adc", "--rate", "10", "--count", "1", "--hub", "127.0.0.1:11500:99"),
         "'127.0.0.1:11500:99'"),  # was read as port 99 of '127.0.0.1:11500'
        (("connect", "hub", "hub.local:1500:1"), "'hub.local:1500:1'"),
        (("bench", "throughput", "127.0.0.1:1:2"), "'127.0.0.1:1:2'"),
        (("dump", "hub", "127.0.0.1", "--listen", "[::1"), "'[::1'"),
        (("connect", "pioneer", "127.0.0.1:8101:1"), "'127.0.0.1:8101:1'"),
        (("connect", "pioneer", "bad url"), "'bad url'"),
        (("connect", "arm", "127.0.0.1:11000"), "--state-port"),  # ports have options
        (("record", "--arm", "127.0.0.1:11000", "-o", "x.mcap"), "--state-port"),
        (("serve", "--port", "0", "--bind", "0.0.0.0:1500"), "'0.0.0.0:1500'"),
        (("serve", "--port", "0", "--gpsd", "localhost:2947:1"), "'localhost:2947:1'"),
        (("sim", "pioneer", "--port", "0", "--bind", "local host"), "'local host'"),
        (("sim", "abb", "--motion-port", "0", "--state-port", "0", "--bind", "[::1]:5"),
         "'[::1]:5'"),
    ],
)  # fmt: skip
def test_a_malformed_address_is_a_usage_error_naming_it(args: tuple[str, ...], named: str) -> None:
    line = one_line_error(run(*args), 2)
    assert named in line and "Traceback" not in line, line


def test_serve_refuses_a_malformed_pioneer_url() -> None:
    """The README: a malformed --pioneer URL is refused at start (it ran, retrying)."""
    line = one_line_error(run("serve", "--port", "0", "--pioneer", "bad url", timeout=60), 2)
    assert "pioneer 'bad url'" in line and "neither a serial port nor a TCP address" in line


@needs_ipv6
def test_an_ipv6_hub_is_reached_by_every_hub_command(hub6: int) -> None:
    address = f"[::1]:{hub6}"
    proc = run("subscribe", "adc", "--rate", "50", "--count", "3", "--format", "csv",
               "--hub", address)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert len(proc.stdout.splitlines()) == 4  # header + 3 samples
    proc = run("connect", "hub", address, "--once", "--json")
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["hub"] == f"tcp://{address}"


@needs_ipv6
def test_serve_binds_ipv6_and_subscribe_reaches_it() -> None:
    with running("serve", "--sim", "--port", "0", "--bind", "[::1]") as server:
        assert server.stdout is not None
        line = server.stdout.readline()
        found = re.search(r"tcp://\[::1\]:(\d+)", line)
        assert found, line + server.stderr.read() if server.stderr else line
        proc = run("subscribe", "imu", "--rate", "50", "--count", "2", "--format", "csv",
                   "--hub", f"[::1]:{found[1]}")  # fmt: skip
        assert proc.returncode == 0, proc.stderr


@needs_ipv6
def test_a_pioneer_and_an_arm_on_ipv6_loopback() -> None:
    with PioneerSim() as simulator:
        url = simulator.serve_tcp("::1", 0)
        assert url.startswith("tcp://[::1]:")
        proc = run("connect", "pioneer", url, "--once", "--json", "--no-laser")
        assert proc.returncode == 0, proc.stderr
        assert json.loads(proc.stdout)["identity"]["type"] == "Pioneer"
    with AbbSim(state_ms=10.0) as sim:
        motion, state = sim.serve_tcp("::1", 0, 0)
        assert motion.startswith("tcp://[::1]:")
        proc = run("connect", "arm", "[::1]", "--state-port", state.rsplit(":", 1)[1], "--once",
                   "--json")  # fmt: skip
        assert proc.returncode == 0, proc.stderr
        assert len(json.loads(proc.stdout)["joints_rad"]) == 6
