"""Shared pytest configuration: tests/ is importable (``import reference``), the hardware
variables are read (``hardware.py``), Hypothesis runs without per-example deadlines, and the
CLI processes the tests start can be interrupted."""

from __future__ import annotations

import os
import signal
import sys

from hypothesis import HealthCheck, settings

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import hardware  # noqa: F401 - reads ROBOCLI_PIONEER/ARM/HUB, then clears them

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
