"""Keyboard driving, independent of the terminal: keys in, velocity set-points out.

Terminals report key presses (and auto-repeats), never releases, so a key counts as held
while presses keep coming; ``release_timeout`` after the last one the robot is told to stop.
The controller is pure logic with explicit times, so tests run it on synthetic clocks.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from robocli.devices.keys import QUIT_KEYS, fresh_keys

#: key name -> (forward, turn) direction; arrows and WASD
KEYMAP: dict[str, tuple[int, int]] = {
    "up": (1, 0), "w": (1, 0),
    "down": (-1, 0), "s": (-1, 0),
    "left": (0, 1), "a": (0, 1),
    "right": (0, -1), "d": (0, -1),
}  # fmt: skip
STOP_KEYS = frozenset({"space", " "})


@dataclass
class TeleopController:
    """Turns key presses into (v m/s, w rad/s)."""

    max_v: float = 0.4
    max_w: float = 1.0
    release_timeout: float = 0.45

    def __post_init__(self) -> None:
        self._direction = (0, 0)
        self._last_key = -1e9
        self.quit = False

    def key(self, name: str, now: float) -> None:
        """Feed one key press (name as in :data:`KEYMAP`, ``space``, ``q``...)."""
        name = name.lower()
        if name in QUIT_KEYS:
            self.quit = True
            self._direction = (0, 0)
        elif name in STOP_KEYS:
            self._direction = (0, 0)
        elif name in KEYMAP:
            self._direction = KEYMAP[name]
            self._last_key = now

    def command(self, now: float) -> tuple[float, float]:
        """The set-point at time ``now``: zero once no key came for ``release_timeout``."""
        if self.quit or now - self._last_key > self.release_timeout:
            self._direction = (0, 0)
        fwd, turn = self._direction
        return (fwd * self.max_v, turn * self.max_w)


class Drivable(Protocol):
    def set_velocity(self, v: float, w: float = 0.0) -> None: ...

    def stop(self) -> None: ...


def run_teleop(
    robot: Drivable,
    read_key: Callable[[float], str | None],
    controller: TeleopController,
    *,
    period: float = 0.05,
    on_update: Callable[[float, float], None] | None = None,
    clock: Callable[[], float] = time.monotonic,
) -> None:
    """Drive ``robot`` until a quit key; ``read_key(timeout)`` returns a key name or None.
    The robot is stopped on every way out (quit, exception, Ctrl-C), and after a stall of
    this loop (keys typed meanwhile are discarded: :func:`~robocli.devices.keys.fresh_keys`)."""
    last: tuple[float, float] | None = None
    read_key = fresh_keys(read_key, controller.release_timeout, clock)
    try:
        while not controller.quit:
            key = read_key(period)
            now = clock()
            if key is not None:
                controller.key(key, now)
            v, w = controller.command(now)
            if (v, w) != last:
                robot.set_velocity(v, w)
                last = (v, w)
                if on_update is not None:
                    on_update(v, w)
    finally:
        robot.stop()
