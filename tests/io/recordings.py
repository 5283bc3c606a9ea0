"""Recordings the tests make to read back: a Pioneer driving a curve with its laser on, and
an arm's move (``from tests.io.recordings import record_pioneer_drive``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from robocli.devices.arm import Arm
from robocli.devices.pioneer import Pioneer
from robocli.io.record import Recorder
from tests.waiting import wait_for


def record_pioneer_drive(path: Path, url: str, scans: int = 1, **recorder: Any) -> Any:
    """The Pioneer at ``url`` driving a curve with its laser on, recorded into ``path`` from
    the handshake on (15 SIPs, then ``scans`` laser scans); ``recorder`` as the
    :class:`Recorder`'s own: the recorder's stats."""
    with Recorder(path, **recorder) as rec:
        listener = rec.listener("pioneer", "arcos", url=url)
        with Pioneer.connect(url, listeners=[listener], laser=True) as robot:
            rec.add(robot, listener.name)
            robot.enable_motors()
            robot.set_velocity(0.3, 0.4)
            for _ in range(15):
                robot.wait_for_sip()
            for _ in range(scans):
                robot.sim.wait_for_laser(10.0)
    return rec.stats


def record_arm_move(path: Path, motion_port: int, state_port: int) -> None:
    """The arm at these loopback ports moving to a pose and back to idle, recorded into
    ``path`` until it holds more than 20 joint_feedback samples."""
    samples: list[Any] = []
    with Recorder(path) as rec, Arm.connect("127.0.0.1", motion_port, state_port) as arm:
        arm.add_listener(samples.append, kind="samples")
        rec.add(arm)
        arm.move_to(np.radians([20, 10, 5, 0, 30, 10]), duration=0.5)
        arm.wait_until_idle(20)
        wait_for(
            lambda: sum(s.source == "joint_feedback" for s in samples) > 20,
            "more than 20 joint_feedback samples",
        )
