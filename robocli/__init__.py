"""robocli: drive robots and read their sensors from a laptop, byte-exact protocols.

``from robocli import Pioneer`` works; the heavy modules load on first use, so importing
robocli (and running ``robocli --help``) stays fast.
"""

from __future__ import annotations

import importlib
import logging
from typing import TYPE_CHECKING, Any

from robocli._version import __version__

if TYPE_CHECKING:
    from robocli.devices.arm import Arm
    from robocli.devices.hub.over_zenoh import ZenohHub
    from robocli.devices.pioneer import Pioneer, PioneerState
    from robocli.errors import RobocliError

# The library never prints: without the application's logging set up, log records go nowhere.
logging.getLogger("robocli").addHandler(logging.NullHandler())

_LAZY = {
    "Arm": "robocli.devices.arm",
    "Hub": "robocli.devices.hub.client",
    "Pioneer": "robocli.devices.pioneer",
    "PioneerState": "robocli.devices.pioneer",
    "RobocliError": "robocli.errors",
    "ZenohHub": "robocli.devices.hub.over_zenoh",
}

__all__ = ["Arm", "Hub", "Pioneer", "PioneerState", "RobocliError", "ZenohHub", "__version__"]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'robocli' has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)
