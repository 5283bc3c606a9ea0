"""The hardware the suite runs against, named by the variables the CLI reads
(:mod:`robocli.defaults`, README "Environment"): ``ROBOCLI_PIONEER`` (a PORT or URL),
``ROBOCLI_ARM`` (a controller's HOST; ports 11000/11002), ``ROBOCLI_HUB`` (``HOST[:PORT]``).

Read once, when the suite starts (``tests/conftest.py`` imports this module), and taken out
of the environment then: every other test, and every robocli process a test starts, runs
as a user without these variables, against the built-in simulators.
"""

from __future__ import annotations

import os

from robocli.defaults import ARM_ENV, HUB_ENV, PIONEER_ENV

VARIABLES = {"pioneer": PIONEER_ENV, "arm": ARM_ENV, "hub": HUB_ENV}
#: device -> its address ("" when the variable is unset: the hardware tests skip).
HARDWARE = {device: os.environ.pop(var, "").strip() for device, var in VARIABLES.items()}
