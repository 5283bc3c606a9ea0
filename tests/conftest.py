"""Shared pytest configuration: tests/ is importable (``import reference``), and Hypothesis
runs without per-example deadlines."""

from __future__ import annotations

import os
import sys

from hypothesis import HealthCheck, settings

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

# Hypothesis checks properties, not speed: on a loaded 2-vCPU machine one example can take
# longer than its default 200 ms deadline, which would make a correct test flaky.
settings.register_profile("robocli", deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("robocli")
