"""Built-in simulators as the tests serve them: on an ephemeral loopback port."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Any

from robocli.sim.pioneer.server import PioneerSim


@contextlib.contextmanager
def pioneer_on_loopback(model: str = "p3dx", **kwargs: Any) -> Iterator[PioneerSim]:
    """A :class:`PioneerSim` (``kwargs`` as its own) serving TCP on 127.0.0.1, any port."""
    with PioneerSim(model, **kwargs) as simulator:
        simulator.serve_tcp("127.0.0.1", 0)
        yield simulator
