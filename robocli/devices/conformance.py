"""The static half of the Device contract: ``mypy --strict`` (``make lint``) checks here that
every client is a :class:`~robocli.devices.base.Device`; ``tests/devices/test_contract.py``
checks the behaviour. Nothing here runs: the imports are for the type checker only."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from robocli.devices.arm import Arm
    from robocli.devices.base import Device
    from robocli.devices.hub.client import Hub
    from robocli.devices.hub.over_zenoh import ZenohHub
    from robocli.devices.laser import Laser
    from robocli.devices.pioneer import Pioneer
    from robocli.devices.pioneer.over_zenoh import RemotePioneer

    def every_client_is_a_device(
        pioneer: Pioneer, arm: Arm, hub: Hub, zenoh_hub: ZenohHub, laser: Laser,
        remote: RemotePioneer,
    ) -> list[Device]:  # fmt: skip
        return [pioneer, arm, hub, zenoh_hub, laser, remote]
