"""Waiting for an event in a test (``from tests.waiting import wait_for``): poll a condition until
it holds, with a deadline that only bounds a failure, never a duration that is asserted."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")

DEADLINE_S = 30.0  #: long enough for a loaded machine (make test-load); a failure only waits it
POLL_S = 0.01


def wait_for(condition: Callable[[], T], what: str, timeout: float = DEADLINE_S) -> T:
    """The first true value of ``condition()``; an AssertionError naming ``what`` once
    ``timeout`` seconds passed without one."""
    end = time.monotonic() + timeout
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > end:
            raise AssertionError(f"not within {timeout:g} s: {what}")
        time.sleep(POLL_S)


__all__ = ["DEADLINE_S", "wait_for"]
