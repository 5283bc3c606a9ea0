"""Where each device is looked for when no address is given, and the environment variable
that says otherwise: one name per device, read by the CLI (every command that takes that
device's address, shown in its ``--help``), by ``robocli doctor``, and by the test suite to
run against hardware. Only the standard library: the CLI imports this at start-up.

=====================  ==================================  =============================
variable               what it holds                       default
=====================  ==================================  =============================
``ROBOCLI_PIONEER``    a Pioneer's PORT or URL             ``tcp://127.0.0.1:8101``
``ROBOCLI_ARM``        an arm controller's HOST            ``127.0.0.1`` (11000, 11002)
``ROBOCLI_HUB``        a sensor hub's ``HOST[:PORT]``      ``127.0.0.1:1500``
=====================  ==================================  =============================
"""

from __future__ import annotations

import os

PIONEER_ENV = "ROBOCLI_PIONEER"
ARM_ENV = "ROBOCLI_ARM"
HUB_ENV = "ROBOCLI_HUB"

#: MobileSim's port, where ``robocli sim pioneer`` listens too.
PIONEER_URL = "tcp://127.0.0.1:8101"
ARM_HOST = "127.0.0.1"
ARM_MOTION_PORT = 11000
ARM_STATE_PORT = 11002
HUB_ADDRESS = "127.0.0.1:1500"

__all__ = [
    "ARM_ENV",
    "ARM_HOST",
    "ARM_MOTION_PORT",
    "ARM_STATE_PORT",
    "HUB_ADDRESS",
    "HUB_ENV",
    "PIONEER_ENV",
    "PIONEER_URL",
    "address",
]


def address(device: str) -> tuple[str, bool]:
    """``(address, from_env)`` of ``device`` (``pioneer``, ``arm`` or ``hub``): its
    variable's value when set and not blank, else the default above."""
    env, default = {
        "pioneer": (PIONEER_ENV, PIONEER_URL),
        "arm": (ARM_ENV, ARM_HOST),
        "hub": (HUB_ENV, HUB_ADDRESS),
    }[device]
    value = os.environ.get(env, "").strip()
    return (value, True) if value else (default, False)
