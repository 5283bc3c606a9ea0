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

#: module -> the names it defines, each imported on first access (PEP 562)
_LAZY_BY_MODULE: dict[str, tuple[str, ...]] = {
    # device clients and what they return
    "robocli.devices.base": ("Device", "ListenerHandle", "Stats"),
    "robocli.devices.simulators": ("Simulator",),
    "robocli.devices.stats": ("LinkStats",),
    "robocli.devices.pioneer": (
        "Pioneer", "PioneerState", "PioneerStats", "RobotIdentity", "LaserScan", "SimStatus",
        "GpsFix", "WatchdogTrip", "WatchdogTripped",
    ),
    "robocli.devices.pioneer.simulated": ("PioneerSimulator",),
    "robocli.devices.arm": (
        "Arm", "ArmStatus", "JointSample", "JointRecorder", "Point", "StillMoving", "TooFewSamples",
    ),
    "robocli.devices.hub.client": ("Hub",),
    "robocli.devices.hub.decode": ("Reading",),
    "robocli.devices.hub.over_zenoh": ("ZenohHub",),
    "robocli.devices.hub.serial": ("VirtualSerial",),
    "robocli.devices.create": ("Create", "CreateState", "CreateOdometry"),
    "robocli.devices.laser": (
        "Laser", "LaserInfo", "Scan", "MountedLaser", "PlacedScan", "SensorClock",
    ),
    "robocli.devices.pioneer.over_zenoh": ("RemotePioneer",),
    "robocli.bridge.pioneer": ("PioneerBridge",),
    "robocli.bridge.arm": ("ArmBridge",),
    # addresses
    "robocli.addresses": ("DeviceURL", "InvalidURL", "parse_device_url"),
    "robocli.transports": ("Transport",),
    # errors
    "robocli.errors": (
        "ChecksumError", "ConnectionLost", "DeviceError", "FramingError", "InvalidArgument",
        "ProtocolError", "RobocliError", "StaleWrite", "TimeoutError", "TransportError",
        "UnknownRobotError",
    ),
    # simulators, the hub, recording, models
    "robocli.sim.pioneer.server": ("PioneerSim",),
    "robocli.sim.abb.server": ("AbbSim",),
    "robocli.sim.hokuyo.server": ("HokuyoSim",),
    "robocli.sim.create": ("CreateSim",),
    "robocli.sim.world": ("World",),
    "robocli.hub_server.server": ("HubServer",),
    "robocli.io.record.recorder": ("Recorder",),
    "robocli.io.record.live": ("LiveView",),
    "robocli.kinematics.model": ("RobotModel",),
    "robocli.robots.pioneer": ("RobotParams",),
}  # fmt: skip
#: name -> the module that defines it
_LAZY = {name: module for module, names in _LAZY_BY_MODULE.items() for name in names}

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
