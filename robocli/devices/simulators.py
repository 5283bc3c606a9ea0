"""``sim://`` URLs: the built-in simulator of a device, started in-process on loopback.

``Pioneer.connect("sim://")``, ``Arm.connect("sim://?profile=generic")``,
``Hub.connect("sim://")``, ``Laser.connect("sim://utm-30lx")``: :func:`start` serves the
simulator on ephemeral 127.0.0.1 ports and gives the URL to connect to; the device owns the
simulator from then on and closes it in its ``close()`` (:func:`adopt`). What follows
``sim://`` is the model (the Pioneer's subtype, the arm's model file, the laser's model);
the query's options go to the simulator's constructor (``time_scale=4``, ``seed=1``),
numbers and ``true``/``false`` converted. The simulators are imported only here, when a
``sim://`` URL is opened: the devices' modules do not load them.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from robocli._wiring import SIMULATORS
from robocli.addresses import DeviceURL
from robocli.closing import closed_on_error
from robocli.errors import InvalidArgument

log = logging.getLogger("robocli.devices.simulators")

__all__ = ["STARTERS", "Simulator", "adopt", "connect_to", "options", "start"]

#: Options a ``sim://`` query may not set: where the simulator listens is loopback, always.
_RESERVED = frozenset({"host", "bind", "port", "motion_port", "state_port"})


@dataclass
class Simulator:
    """A running simulator: ``server`` (its object, e.g. a
    :class:`~robocli.sim.pioneer.server.PioneerSim`), ``urls`` (where each of its ports
    listens: ``{"": url}``, or the arm's ``{"motion": ..., "state": ...}``)."""

    server: Any
    urls: dict[str, str]

    @property
    def url(self) -> str:
        return next(iter(self.urls.values()))

    def port(self, name: str) -> int:
        return int(self.urls[name].rsplit(":", 1)[1])

    def close(self) -> None:
        """Stop the simulator: its links drop, its threads end. Idempotent."""
        self.server.close()


def _value(text: str) -> Any:
    low = text.lower()
    if low in ("true", "false"):
        return low == "true"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def options(url: DeviceURL, **fixed: Any) -> dict[str, Any]:
    """The simulator's constructor options: ``fixed``, then the URL's query (converted)."""
    bad = sorted(_RESERVED & url.options.keys())
    if bad:
        raise InvalidArgument(f"{url.text!r}: a sim:// URL cannot set {', '.join(bad)} "
                              "(the simulator listens on ephemeral loopback ports)")  # fmt: skip
    return {**fixed, **{k: _value(v) for k, v in url.options.items()}}


def _pioneer(url: DeviceURL, **fixed: Any) -> Simulator:
    from robocli.sim.pioneer.server import PioneerSim

    server = PioneerSim(url.model or "p3dx", **options(url, **fixed))
    return Simulator(server, {"": server.serve_tcp("127.0.0.1", 0)})


def _arm(url: DeviceURL, **fixed: Any) -> Simulator:
    from robocli.sim.abb.server import AbbSim

    given = options(url, **{"state_ms": 5.0, "feedback": True, **fixed})
    server = AbbSim(url.model or "irb120", **given)
    motion, state = server.serve_tcp("127.0.0.1", 0, 0)
    return Simulator(server, {"motion": motion, "state": state})


def _laser(url: DeviceURL, **fixed: Any) -> Simulator:
    from robocli.sim.hokuyo import HokuyoSim

    server = HokuyoSim(url.model or "utm-30lx", **options(url, **fixed))
    return Simulator(server, {"": server.serve_tcp("127.0.0.1", 0)})


#: The simulators of the robots, by device. The hub's is the hub server, whose sources use
#: the clients: ``robocli/__init__.py`` gives it (:data:`robocli._wiring.SIMULATORS`).
STARTERS: dict[str, Callable[..., Simulator]] = {
    "pioneer": _pioneer, "arm": _arm, "laser": _laser,
}  # fmt: skip


def start(device: str | Callable[..., Simulator], url: DeviceURL, **fixed: Any) -> Simulator:
    """Start the simulator of ``device`` (``pioneer``, ``arm``, ``laser``, ``hub``, or a function
    ``(url, **options) -> Simulator``) that ``url`` (a ``sim`` :class:`DeviceURL`) asks
    for; ``fixed``: options the client's own arguments imply (the arm's byte order),
    overridden by the URL's. An option the simulator does not have, or a value it
    refuses, is an :class:`InvalidArgument`."""
    if isinstance(device, str):
        starter = STARTERS[device] if device in STARTERS else SIMULATORS[device]
    else:
        starter = device
    try:
        return starter(url, **fixed)
    except (TypeError, ValueError, LookupError) as exc:
        if isinstance(exc, InvalidArgument):
            raise
        raise InvalidArgument(f"{url.text!r}: the simulator refused it: {exc}") from None


def adopt(device: Any, simulator: Simulator) -> None:
    """Make ``device`` own ``simulator``: its ``close()`` closes it (after the device's
    own link), and :attr:`simulator` names it (a test stops it to see a link die)."""
    device.simulator = simulator
    log.info("%r runs on its own simulator at %s", device, simulator.url)


def connect_to(device: str | Callable[..., Simulator], url: DeviceURL,
               connect: Callable[[Simulator], Any],
               **fixed: Any) -> Any:  # fmt: skip
    """Start ``device``'s simulator for ``url``, ``connect(simulator)`` to it and hand the
    simulator to what that returns (:func:`adopt`); a connect that fails stops it again."""
    simulator = start(device, url, **fixed)
    with closed_on_error(simulator):
        client = connect(simulator)
    adopt(client, simulator)
    return client
