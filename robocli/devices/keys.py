"""Keys for driving, fresh: a program that stalled does not replay what was typed meanwhile.

A terminal queues key presses (and auto-repeats) while the program reading them is stopped
(Ctrl-Z, SIGSTOP, a debugger, a suspended laptop). Read one by one afterwards, a held
key's queued repeats would drive the robot on for as long as the stall lasted, after the
key was let go. :func:`fresh_keys` wraps a key reader: after a gap longer than the driving
logic's release time, the queued keys are discarded and a stop key is returned instead.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

log = logging.getLogger("robocli.devices.keys")

#: Queued keys discarded after a stall at most (a bound; a terminal queues a few KiB).
MAX_DISCARD = 65536
#: What a stall reads as: a stop key of every teleop's key map.
STALL_KEY = "space"
#: Keys that end a teleop (kept when typed during a stall).
QUIT_KEYS = frozenset({"q", "esc", "ctrl-c"})

KeyReader = Callable[[float], "str | None"]


def fresh_keys(
    read_key: KeyReader, stall: float, clock: Callable[[], float] = time.monotonic
) -> KeyReader:
    """``read_key(timeout)`` that returns :data:`STALL_KEY` (and discards what is queued)
    when more than ``stall`` seconds passed beyond the reads' own timeouts since the last
    read returned: the program stalled, and keys typed meanwhile are stale."""
    last = clock()

    def read(timeout: float) -> str | None:
        nonlocal last
        key = read_key(timeout)
        now = clock()
        gap = now - last - timeout
        last = now
        if gap <= stall:
            return key
        dropped = 0
        while (key or "") not in QUIT_KEYS and dropped < MAX_DISCARD:
            dropped += key is not None
            key = read_key(0)
            if key is None:
                break
        last = clock()
        log.warning("the program stalled for %.1f s: stopped, %d key(s) typed meanwhile "
                    "discarded", gap, dropped)  # fmt: skip
        return key if (key or "") in QUIT_KEYS else STALL_KEY

    return read


__all__ = ["MAX_DISCARD", "QUIT_KEYS", "STALL_KEY", "KeyReader", "fresh_keys"]
