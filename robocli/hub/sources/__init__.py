"""Hub sources: simulated and real sensors behind one interface (:class:`Source`)."""

from __future__ import annotations

from robocli.hub.sources.base import Batch, PeriodicSource, Source
from robocli.hub.sources.sim import AdcSource, BatterySource, GpsSource, ImuSource

__all__ = [
    "AdcSource",
    "Batch",
    "BatterySource",
    "GpsSource",
    "ImuSource",
    "PeriodicSource",
    "Source",
    "simulated_sources",
]


def simulated_sources() -> dict[str, Source]:
    """One simulated source per sensor kind, by the hub's sensor names."""
    sources: list[Source] = [AdcSource(), ImuSource(), GpsSource(), BatterySource()]
    return {s.name: s for s in sources}
