"""robocli: drive robots and read their sensors from a laptop, byte-exact protocols.

Every public class is importable from here (``from robocli import Pioneer, Arm, Hub,
Laser, RemotePioneer, Recorder, PioneerSim``...); each loads its module on first use, so
importing robocli (and running ``robocli --help``) stays fast. Devices open from one URL
grammar (``sim://``, ``tcp://HOST:PORT``, a serial port, ``zenoh/NAME``; docs/urls.md) and
follow one :class:`Device` surface.
"""

from __future__ import annotations

import importlib
import logging
from typing import TYPE_CHECKING, Any

from robocli import _wiring
from robocli._version import __version__

if TYPE_CHECKING:
    from robocli.addresses import DeviceURL, InvalidURL, parse_device_url
    from robocli.bridge.arm import ArmBridge
    from robocli.bridge.pioneer import PioneerBridge
    from robocli.devices.arm import (
        Arm,
        ArmStatus,
        JointRecorder,
        JointSample,
        Point,
        StillMoving,
        TooFewSamples,
    )
    from robocli.devices.base import Device, ListenerHandle, Stats
    from robocli.devices.hub.client import Hub
    from robocli.devices.hub.decode import Reading
    from robocli.devices.hub.over_zenoh import ZenohHub
    from robocli.devices.laser import (
        Laser,
        LaserInfo,
        MountedLaser,
        PlacedScan,
        Scan,
        SensorClock,
    )
    from robocli.devices.pioneer import (
        GpsFix,
        LaserScan,
        Pioneer,
        PioneerState,
        PioneerStats,
        RobotIdentity,
        SimStatus,
        WatchdogTrip,
        WatchdogTripped,
    )
    from robocli.devices.pioneer.over_zenoh import RemotePioneer
    from robocli.devices.pioneer.simulated import PioneerSimulator
    from robocli.devices.simulators import Simulator
    from robocli.devices.stats import LinkStats
    from robocli.errors import (
        ChecksumError,
        ConnectionLost,
        DeviceError,
        FramingError,
        InvalidArgument,
        ProtocolError,
        RobocliError,
        StaleWrite,
        TimeoutError,
        TransportError,
        UnknownRobotError,
    )
    from robocli.hub_server.server import HubServer
    from robocli.io.record.live import LiveView
    from robocli.io.record.recorder import Recorder
    from robocli.kinematics.model import RobotModel
    from robocli.robots.pioneer import RobotParams
    from robocli.sim.abb.server import AbbSim
    from robocli.sim.hokuyo.server import HokuyoSim
    from robocli.sim.pioneer.server import PioneerSim
    from robocli.sim.world import World
    from robocli.transports import Transport

# The library never prints: without the application's logging set up, log records go nowhere.
logging.getLogger("robocli").addHandler(logging.NullHandler())


def _simulated_hub(url: DeviceURL, **fixed: Any) -> Simulator:
    """The simulated hub of ``Hub.connect("sim://")``: the hub server with simulated sensors,
    on an ephemeral loopback port. Given to the device clients from here (robocli._wiring):
    the hub server stands on them, so they cannot import it."""
    from robocli.devices import simulators
    from robocli.errors import InvalidArgument
    from robocli.hub_server import HubServer

    if url.model:
        raise InvalidArgument(f"{url.text!r}: the simulated hub has no models (give sim://)")
    server = HubServer("127.0.0.1", 0, **simulators.options(url, sim=True, **fixed)).start()
    return simulators.Simulator(server, {"": f"127.0.0.1:{server.port}"})


_wiring.SIMULATORS["hub"] = _simulated_hub

#: name -> the module that defines it, imported on first access (PEP 562)
_LAZY = {
    # device clients and what they return
    "Device": "robocli.devices.base", "ListenerHandle": "robocli.devices.base",
    "Stats": "robocli.devices.base",
    "Simulator": "robocli.devices.simulators", "LinkStats": "robocli.devices.stats",
    "Pioneer": "robocli.devices.pioneer", "PioneerState": "robocli.devices.pioneer",
    "PioneerStats": "robocli.devices.pioneer", "RobotIdentity": "robocli.devices.pioneer",
    "LaserScan": "robocli.devices.pioneer", "SimStatus": "robocli.devices.pioneer",
    "GpsFix": "robocli.devices.pioneer", "WatchdogTrip": "robocli.devices.pioneer",
    "WatchdogTripped": "robocli.devices.pioneer",
    "PioneerSimulator": "robocli.devices.pioneer.simulated",
    "Arm": "robocli.devices.arm", "ArmStatus": "robocli.devices.arm",
    "JointSample": "robocli.devices.arm", "JointRecorder": "robocli.devices.arm",
    "Point": "robocli.devices.arm",
    "StillMoving": "robocli.devices.arm", "TooFewSamples": "robocli.devices.arm",
    "Hub": "robocli.devices.hub.client", "Reading": "robocli.devices.hub.decode",
    "ZenohHub": "robocli.devices.hub.over_zenoh",
    "VirtualSerial": "robocli.devices.hub.serial",
    "Create": "robocli.devices.create", "CreateState": "robocli.devices.create",
    "CreateOdometry": "robocli.devices.create",
    "Laser": "robocli.devices.laser", "LaserInfo": "robocli.devices.laser",
    "Scan": "robocli.devices.laser", "MountedLaser": "robocli.devices.laser",
    "PlacedScan": "robocli.devices.laser", "SensorClock": "robocli.devices.laser",
    "RemotePioneer": "robocli.devices.pioneer.over_zenoh",
    "PioneerBridge": "robocli.bridge.pioneer",
    "ArmBridge": "robocli.bridge.arm",
    # addresses
    "DeviceURL": "robocli.addresses", "InvalidURL": "robocli.addresses",
    "parse_device_url": "robocli.addresses", "Transport": "robocli.transports",
    # errors
    **{name: "robocli.errors" for name in (
        "ChecksumError", "ConnectionLost", "DeviceError", "FramingError", "InvalidArgument",
        "ProtocolError", "RobocliError", "StaleWrite", "TimeoutError", "TransportError",
        "UnknownRobotError")},
    # simulators, the hub, recording, models
    "PioneerSim": "robocli.sim.pioneer.server", "AbbSim": "robocli.sim.abb.server",
    "HokuyoSim": "robocli.sim.hokuyo.server", "CreateSim": "robocli.sim.create",
    "World": "robocli.sim.world",
    "HubServer": "robocli.hub_server.server", "Recorder": "robocli.io.record.recorder",
    "LiveView": "robocli.io.record.live", "RobotModel": "robocli.kinematics.model",
    "RobotParams": "robocli.robots.pioneer",
}  # fmt: skip

__all__ = [
    "AbbSim",
    "Arm",
    "ArmBridge",
    "ArmStatus",
    "ChecksumError",
    "ConnectionLost",
    "Create",
    "CreateOdometry",
    "CreateSim",
    "CreateState",
    "Device",
    "DeviceError",
    "DeviceURL",
    "FramingError",
    "GpsFix",
    "HokuyoSim",
    "Hub",
    "HubServer",
    "InvalidArgument",
    "InvalidURL",
    "JointRecorder",
    "JointSample",
    "Laser",
    "LaserInfo",
    "LaserScan",
    "LinkStats",
    "ListenerHandle",
    "LiveView",
    "MountedLaser",
    "Pioneer",
    "PioneerBridge",
    "PioneerSim",
    "PioneerSimulator",
    "PioneerState",
    "PioneerStats",
    "PlacedScan",
    "Point",
    "ProtocolError",
    "Reading",
    "Recorder",
    "RemotePioneer",
    "RobocliError",
    "RobotIdentity",
    "RobotModel",
    "RobotParams",
    "Scan",
    "SensorClock",
    "SimStatus",
    "Simulator",
    "StaleWrite",
    "Stats",
    "StillMoving",
    "TimeoutError",
    "TooFewSamples",
    "Transport",
    "TransportError",
    "UnknownRobotError",
    "VirtualSerial",
    "WatchdogTrip",
    "WatchdogTripped",
    "World",
    "ZenohHub",
    "__version__",
    "parse_device_url",
]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'robocli' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # the next access is a plain attribute
    return value


def __dir__() -> list[str]:
    return __all__
