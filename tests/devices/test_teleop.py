"""Keyboard driving logic on a synthetic clock; and a scripted session against the simulator."""

from __future__ import annotations

import pytest

from robocli.devices.pioneer.teleop import TeleopController


def test_held_key_drives_and_release_stops_within_timeout() -> None:
    c = TeleopController(max_v=0.5, max_w=1.2, release_timeout=0.45)
    c.key("up", 0.0)
    assert c.command(0.0) == (0.5, 0.0)
    for t in (0.5, 0.53, 0.56):  # auto-repeat keeps it going
        c.key("up", t)
        assert c.command(t) == (0.5, 0.0)
    assert c.command(0.56 + 0.44) == (0.5, 0.0)
    assert c.command(0.56 + 0.46) == (0.0, 0.0)  # released: stopped within 0.5 s


@pytest.mark.parametrize(
    ("key", "expected"),
    [
        ("left", (0.0, 1.2)),
        ("d", (0.0, -1.2)),
        ("s", (-0.5, 0.0)),
        ("W", (0.5, 0.0)),
    ],
)
def test_keymap(key: str, expected: tuple[float, float]) -> None:
    c = TeleopController(max_v=0.5, max_w=1.2)
    c.key(key, 1.0)
    assert c.command(1.0) == expected


def test_space_stops_and_q_quits() -> None:
    c = TeleopController()
    c.key("up", 0.0)
    c.key("space", 0.1)
    assert c.command(0.1) == (0.0, 0.0)
    c.key("up", 0.2)
    c.key("q", 0.3)
    assert c.quit and c.command(0.3) == (0.0, 0.0)
    c.key("x", 0.4)  # unknown keys are ignored


class _Terminal:
    """A terminal on a synthetic clock: queued keys are read one per call; an empty queue
    waits out the timeout. :meth:`stall` stops the program for ``seconds`` while ``keys``
    (a held key's auto-repeats) queue up."""

    def __init__(self) -> None:
        self.now = 0.0
        self.queue: list[str] = []
        self.script: list[str] = []

    def clock(self) -> float:
        return self.now

    def stall(self, seconds: float, keys: list[str]) -> None:
        self.now += seconds
        self.queue += keys

    def read_key(self, timeout: float) -> str | None:
        if self.queue:
            self.now += 0.001
            return self.queue.pop(0)
        if self.script:
            step = self.script.pop(0)
            if step == "stall":
                self.stall(5.0, ["up"] * 150)  # 5 s of a 30 Hz auto-repeat, let go since
                return None
            self.now += 0.03
            return step
        self.now += timeout
        return "q" if self.now > 30 else None


def test_keys_typed_during_a_stall_do_not_drive_the_robot_on() -> None:
    """A held key's repeats queued while the program was stopped are not replayed: the
    robot stops when the loop finds the stall, and moves again on a fresh press."""
    from robocli.devices.pioneer.teleop import run_teleop

    term = _Terminal()
    term.script = ["up", "up", "up", "stall"] + [None] * 20 + ["left"]  # type: ignore[list-item]
    sent: list[tuple[float, float, float]] = []

    class Robot:
        def set_velocity(self, v: float, w: float = 0.0) -> None:
            sent.append((term.now, v, w))

        def stop(self) -> None:
            sent.append((term.now, 0.0, 0.0))

    run_teleop(Robot(), term.read_key, TeleopController(max_v=0.4, max_w=1.0),
               clock=term.clock)  # fmt: skip
    after = [(v, w) for t, v, w in sent if t >= 5.0]
    assert after[0] == (0.0, 0.0), "the stall did not stop the robot"
    assert (0.4, 0.0) not in after, "a key typed during the stall drove the robot on"
    assert (0.0, 1.0) in after  # a fresh press after the stall drives


def test_a_quit_typed_during_a_stall_is_kept() -> None:
    from robocli.devices.keys import fresh_keys

    term = _Terminal()
    read = fresh_keys(term.read_key, 0.45, term.clock)
    term.stall(5.0, ["up", "up", "q", "up"])
    assert read(0.05) == "q"
    term.stall(5.0, ["up", "up"])
    assert read(0.05) == "space" and term.queue == []  # the repeats are discarded
