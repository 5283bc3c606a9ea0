"""The sensor hub's client over ros4mat: :class:`Hub` (the client), its link (:mod:`.link`),
the SUBSCRIBE settings (:mod:`.subscription`), the hub's clock (:mod:`.clock`), the reply
decoder (:mod:`.decode`) and the command-line helpers built on it (:mod:`.tools`). A serial
port of the hub as a local one: :class:`VirtualSerial` (:mod:`.serial`), on a local pty
(:mod:`.relay`), as a pyserial ``robocli://`` URL (:mod:`.serial_url`), over Zenoh
(:mod:`.zenoh_serial`)."""

from robocli.devices.hub.client import Hub, Reading
from robocli.devices.hub.over_zenoh import ZenohHub  # (so that Hub.connect("zenoh/NAME") works)
from robocli.devices.hub.serial import VirtualSerial

__all__ = ["Hub", "Reading", "VirtualSerial", "ZenohHub"]
