"""Hub sources: simulated and real sensors behind one interface (:class:`Source`)."""

from __future__ import annotations

from robocli.hub_server.sources.base import Batch, PeriodicSource, Source
from robocli.hub_server.sources.imaging import CameraSource, DepthSource, LaserSource, StereoSource
from robocli.hub_server.sources.opencv import OpenCvCameraSource, opencv_available
from robocli.hub_server.sources.pioneer import PioneerAdcSource, PioneerBatterySource, PioneerLink
from robocli.hub_server.sources.real import GpsdSource, SerialPorts, SysinfoSource, parse_host_port
from robocli.hub_server.sources.sim import AdcSource, BatterySource, GpsSource, ImuSource

__all__ = [
    "AdcSource",
    "Batch",
    "BatterySource",
    "CameraSource",
    "DepthSource",
    "GpsSource",
    "GpsdSource",
    "ImuSource",
    "LaserSource",
    "OpenCvCameraSource",
    "PeriodicSource",
    "PioneerAdcSource",
    "PioneerBatterySource",
    "PioneerLink",
    "SerialPorts",
    "Source",
    "StereoSource",
    "SysinfoSource",
    "hub_sources",
    "parse_host_port",
]


def hub_sources(
    sim: bool = True, gpsd: str | None = None, pioneer: str | None = None
) -> dict[str, Source]:
    """The sources of a hub by sensor name: every simulated sensor when ``sim``; this
    machine's system info always; without ``sim``, a real camera when OpenCV is installed
    (``robocli-robots[camera]``); the GPS from gpsd (``"HOST[:PORT]"``) and the battery and ADC from
    a Pioneer at URL ``pioneer`` when given (they replace the simulated ones)."""
    sources: list[Source] = [SysinfoSource()]
    if sim:
        sources += [AdcSource(), ImuSource(), GpsSource(), BatterySource(), CameraSource(),
                    StereoSource(), DepthSource(), LaserSource()]  # fmt: skip
    elif opencv_available():
        sources.append(OpenCvCameraSource())
    if gpsd:
        sources.append(GpsdSource(*parse_host_port(gpsd, 2947)))
    if pioneer:
        link = PioneerLink(pioneer)
        sources += [PioneerBatterySource(link), PioneerAdcSource(link)]
    return {s.name: s for s in sources}
