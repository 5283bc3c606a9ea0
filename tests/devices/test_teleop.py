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
