"""Pioneer robots over ARCOS: :class:`Pioneer` (the client), its state and link modules."""

from robocli.devices.pioneer.client import (
    PacketListener,
    Pioneer,
    PioneerStats,
    WatchdogTrip,
    WatchdogTripped,
)
from robocli.devices.pioneer.laser import GpsFix, LaserScan, SimStatus
from robocli.devices.pioneer.state import PioneerState, RobotIdentity

#: The link counters of a Pioneer (kept under its historical name).
LinkStats = PioneerStats

__all__ = [
    "GpsFix",
    "LaserScan",
    "LinkStats",
    "PacketListener",
    "Pioneer",
    "PioneerState",
    "PioneerStats",
    "RobotIdentity",
    "SimStatus",
    "WatchdogTrip",
    "WatchdogTripped",
]
