"""Keys from a terminal in cbreak mode (Ctrl-C still interrupts): what the live views and
teleop read ``q``, arrows and WASD with."""

from __future__ import annotations

import contextlib
import os
import select
import sys
from collections.abc import Callable, Iterator

__all__ = ["QUIT_KEYS", "KeyReader", "keyboard", "raw_terminal"]

#: ``read_key(timeout) -> name | None``: a key's name (``"a"``, ``"up"``, ``"space"``,
#: ``"esc"``, ``"ctrl-c"``), or None when none came within ``timeout`` seconds.
KeyReader = Callable[[float], "str | None"]
#: The keys that end a live view.
QUIT_KEYS = ("q", "Q", "esc")
_ARROWS = {"A": "up", "B": "down", "C": "right", "D": "left"}


@contextlib.contextmanager
def keyboard() -> Iterator[KeyReader | None]:
    """Keys from stdin in cbreak mode: yield a :data:`KeyReader`, or None when stdin is not
    a terminal."""
    if not sys.stdin.isatty():
        yield None
        return
    with raw_terminal() as read_key:
        yield read_key


@contextlib.contextmanager
def raw_terminal() -> Iterator[KeyReader]:
    """Put stdin (a terminal) in cbreak mode, restored afterwards; yield a
    :data:`KeyReader`."""
    import termios
    import tty

    fd = sys.stdin.fileno()
    saved = termios.tcgetattr(fd)

    def read_key(timeout: float) -> str | None:
        ready, _, _ = select.select([fd], [], [], timeout)
        if not ready:
            return None
        ch = os.read(fd, 1)
        if ch == b"\x1b":
            more, _, _ = select.select([fd], [], [], 0.01)
            if not more:
                return "esc"
            seq = os.read(fd, 2)
            return _ARROWS.get(seq[-1:].decode(errors="replace"), None)
        if ch == b"\x03":
            return "ctrl-c"
        if ch == b" ":
            return "space"
        return ch.decode(errors="replace")

    try:
        tty.setcbreak(fd)
        yield read_key
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)
