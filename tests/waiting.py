"""Waiting for an event in a test (``from tests.waiting import wait_for``): poll a condition until
it holds, or wait for threads to end, with a deadline that only bounds a failure, never a
duration that is asserted."""

from __future__ import annotations

import threading
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


def run_together(target: Callable[[], object], n: int, timeout: float = DEADLINE_S) -> None:
    """``target`` run by ``n`` threads at once; returns once each has ended (or ``timeout``
    seconds passed for it: the caller asserts what the threads did)."""
    threads = [threading.Thread(target=target) for _ in range(n)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout)


__all__ = ["DEADLINE_S", "run_together", "wait_for"]
