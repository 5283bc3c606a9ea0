"""ros4mat message ids, sizes, status codes and sensor names (protocol version 3): what a
header and a sensor name mean, without the declarations of the bodies (:mod:`.messages`).

Part of :mod:`robocli.protocols.ros4mat` (import from there; its docstring has the facts).
"""

from __future__ import annotations

import enum

from robocli.errors import InvalidArgument, ProtocolError

__all__ = [
    "ALIASES",
    "BATTERY_MAX_CELLS",
    "HEADER_SIZE",
    "INFLATE_STEP",
    "MAX_BODY_SIZE",
    "PORT",
    "PROTOCOL_VERSION",
    "SENSORS",
    "BatteryState",
    "Compression",
    "ComputerState",
    "GpsState",
    "MsgType",
    "SerialStatus",
    "sensor_type",
]


PORT = 1500
PROTOCOL_VERSION = 3
HEADER_SIZE = 27
MAX_BODY_SIZE = 16 * 1024 * 1024
"""Largest body robocli accepts, on the wire and once inflated (the C framer's default)."""
INFLATE_STEP = 64 * 1024
"""Bytes of output zlib may produce per step while inflating a body."""
BATTERY_MAX_CELLS = 8


class MsgType(enum.IntEnum):
    """Message ids: 0x0X commands, 0x1X acks, 0x2X sensor data (request and reply)."""

    CONNECT = 0x01
    QUIT = 0x02
    SUBSCRIBE = 0x03
    UNSUBSCRIBE = 0x04
    SERIAL_CMD = 0x05
    DOUT_CTRL = 0x06
    SERIAL_OPEN = 0x07  # 0x07-0x09, 0x17, 0x2B: robocli's serial stream (.stream)
    SERIAL_WRITE = 0x08
    SERIAL_CLOSE = 0x09
    CONNECT_ACK = 0x11
    SUBSCRIBE_ACK = 0x13
    SERIAL_OPEN_ACK = 0x17
    ADC = 0x20
    IMU = 0x21
    BATTERY = 0x22  # robocli's own definition, see the module docstring
    GPS = 0x23
    WEBCAM = 0x24
    SERIAL_ANS = 0x25
    COMPUTER = 0x26
    HOKUYO = 0x27
    KINECT_DEPTH = 0x28
    KINECT = 0x29
    WEBCAM_STEREO = 0x2A
    SERIAL_DATA = 0x2B


class Compression(enum.IntEnum):
    NONE = 0
    ZLIB = 1


class GpsState(enum.IntEnum):
    NO_FIX = 0x00
    FIX_2D = 0x10
    FIX_3D = 0x20


class SerialStatus(enum.IntEnum):
    OK = 0x00
    NO_OPEN = 0x10
    TIMEOUT = 0x20
    BAD_SELECT = 0x30


class ComputerState(enum.IntEnum):
    OK = 0x00
    ERROR = 0x10


class BatteryState(enum.IntFlag):
    """``state`` bits of robocli's :data:`Battery` record."""

    UNDER_VOLTAGE = 0x01
    OVER_VOLTAGE = 0x02
    OVER_CURRENT = 0x04


SENSORS: dict[str, MsgType] = {
    "adc": MsgType.ADC,
    "imu": MsgType.IMU,
    "battery": MsgType.BATTERY,
    "gps": MsgType.GPS,
    "camera": MsgType.WEBCAM,
    "webcam": MsgType.WEBCAM,
    "computer": MsgType.COMPUTER,
    "ordinateur": MsgType.COMPUTER,
    "hokuyo": MsgType.HOKUYO,
    "kinect_ir": MsgType.KINECT_DEPTH,
    "kinect": MsgType.KINECT,
    "camera_stereo": MsgType.WEBCAM_STEREO,
}
"""Sensor names (the original client's, plus ``computer``/``webcam``/``battery``) -> id."""

ALIASES: dict[str, str] = {
    "laser": "hokuyo",
    "stereo": "camera_stereo",
    "depth": "kinect",
    "sysinfo": "computer",
}
"""robocli's plain names for the sensors whose ros4mat names are hardware models."""


def sensor_type(sensor: str | int) -> MsgType:
    """The message id of a sensor given by name (``"adc"``, or an alias such as ``"laser"``)
    or id. An unknown name is the caller's mistake (:class:`InvalidArgument`), an unknown id
    a protocol one (:class:`ProtocolError`)."""
    if isinstance(sensor, str):
        name = sensor.lower()
        try:
            return SENSORS[ALIASES.get(name, name)]
        except KeyError:
            known = ", ".join(sorted({*SENSORS, *ALIASES} - {"webcam", "ordinateur"}))
            raise InvalidArgument(f"unknown sensor {sensor!r}; known: {known}") from None
    try:
        return MsgType(sensor)
    except ValueError:
        raise ProtocolError(f"unknown ros4mat message id {sensor!r}") from None
