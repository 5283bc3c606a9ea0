"""Shared pytest configuration: the hardware variables are read (``hardware.py``), Hypothesis
runs without per-example deadlines, the CLI processes the tests start can be interrupted, and
the fixtures that tests in several folders use (a hub server, a Zenoh endpoint). tests/ is a
package: helpers are imported as ``from tests.waiting import wait_for``."""

from __future__ import annotations

import signal
from collections.abc import Iterator

import pytest
from hypothesis import HealthCheck, settings

from robocli.hub_server import HubServer
from tests import hardware  # noqa: F401 - reads ROBOCLI_PIONEER/ARM/HUB, then clears them
from tests.peers import free_endpoint

# Hypothesis checks properties, not speed: on a loaded 2-vCPU machine one example can take
# longer than its default 200 ms deadline, which would make a correct test flaky.
settings.register_profile("robocli", deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("robocli")

# A shell without job control starts background jobs with SIGINT ignored, and an ignored signal
# stays ignored across exec: a CI script run with `&` would give every robocli subprocess a
# deaf ear to Ctrl-C, as POSIX intends for background jobs. The Ctrl-C tests need the
# interactive case, so restore a handler here: a caught signal is reset to its default in
# the children.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture
def hub() -> Iterator[HubServer]:
    """A simulated hub server on an ephemeral loopback port (tests of the server and of its
    clients)."""
    with HubServer(port=0, sim=True) as srv:
        yield srv


@pytest.fixture
def endpoint() -> str:
    """A Zenoh ``tcp/127.0.0.1:PORT`` endpoint on a port free a moment ago."""
    return free_endpoint()
