"""Built-in Hokuyo scanner simulator (SCIP 2.0): :class:`HokuyoSim`, the models in
:mod:`~robocli.sim.hokuyo.model`, one client's protocol in :mod:`~robocli.sim.hokuyo.session`,
request framing in :mod:`~robocli.protocols.scip2.framing`."""

from __future__ import annotations

from robocli.sim.hokuyo.model import MODELS, HokuyoModel
from robocli.sim.hokuyo.server import HokuyoSim

__all__ = ["MODELS", "HokuyoModel", "HokuyoSim"]
