"""The devices on real hardware, when the CLI's variables name it (tests/hardware.py):
connect, read the state, leave without moving anything. Skipped otherwise."""

from __future__ import annotations

import pytest

from robocli.devices.arm import Arm
from robocli.devices.hub.client import Hub
from robocli.devices.hub.tools import survey
from robocli.devices.pioneer import Pioneer
from tests.hardware import HARDWARE, VARIABLES


def _needs(device: str) -> pytest.MarkDecorator:
    return pytest.mark.skipif(
        not HARDWARE[device], reason=f"${VARIABLES[device]} names no {device}"
    )


@_needs("pioneer")
def test_a_pioneer_reports_its_identity_and_state() -> None:
    with Pioneer.connect(HARDWARE["pioneer"]) as robot:
        state = robot.wait_for_sip(5.0)
        assert robot.identity.type and robot.params.subtype
        assert state.battery > 0


@_needs("arm")
def test_an_arm_controller_streams_its_joints() -> None:
    with Arm.connect(HARDWARE["arm"], motion=False) as arm:  # the state port only: no motion
        sample = arm.wait_for_state(5.0)
        assert len(sample.joints) == arm.robot.n_joints


@_needs("hub")
def test_a_hub_answers_a_survey() -> None:
    with Hub.connect(HARDWARE["hub"]) as hub:
        info = survey(hub, 0.2)
        assert info["protocol_version"] == 3 and info["client_id"] > 0
