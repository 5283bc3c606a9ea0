"""ros4mat protocol version 3 (the sensor hub's wire format), declared once with ``construct``.

Facts from ``shared/protocols/ros4mat.md`` (the original project's ``exchangeStructs.h``,
server and MATLAB client, LGPL-3.0) and the bytes captured from the original client.
Reimplemented from those facts; no original code is used.

Every packet is the packed little-endian 27-byte :data:`Header` followed by a body of
:func:`body_length` bytes (``uncompress_size``, or ``compress_size`` when zlib-compressed or
when it carries an error text). TCP port :data:`PORT` (1500).

Field names are snake_case versions of the original ones (``clientId`` -> ``client_id``,
``typeCapteur`` -> ``sensor``, ``posAngulaire`` -> ``mag``, ``timestamp`` -> ``t``, ...).
Values are the raw protocol units (volts, g, deg/s, uT, degrees, ...); timestamps are the
robot's ROS clock in seconds (acquisition time for records, send time for
``packet_timestamp``).

**BATTERY (0x22) is robocli's own definition.** Protocol v3 has no battery message; 0x22 is
the free slot between IMU and GPS and the ROS battery driver (``M_Battery``) exists. robocli
declares :data:`Battery` (54 bytes)::

    f32 vtotal (V) | f32 current (A, positive = discharge) | u8 n_cells (0..8)
    | 8 x f32 vcell (V, entries >= n_cells are 0) | u8 state (BatteryState bits)
    | f32 state_of_charge (0..1, NaN = unknown) | f64 t

An early (pre-v3) revision of the original header had a different 37-byte battery record
(state, 6 cell voltages, current, timestamp) at 0x22; robocli's record does not follow it.

Quirks of the original client, documented rather than copied: it casts the serial baud rate
to uint16 (115200 wraps; the wire field is uint32), its stereo ROI parser reads the wrong
arguments, it always sends ``size = 1`` for requests with a body.
"""

from __future__ import annotations

import enum
import math
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import construct as cs
import numpy as np

from robocli.errors import FramingError, ProtocolError
from robocli.protocols.common import plain

PORT = 1500
PROTOCOL_VERSION = 3
HEADER_SIZE = 27
MAX_BODY_SIZE = 16 * 1024 * 1024
"""Largest body robocli accepts (the C framer's default)."""
BATTERY_MAX_CELLS = 8


class MsgType(enum.IntEnum):
    """Message ids: 0x0X commands, 0x1X acks, 0x2X sensor data (request and reply)."""

    CONNECT = 0x01
    QUIT = 0x02
    SUBSCRIBE = 0x03
    UNSUBSCRIBE = 0x04
    SERIAL_CMD = 0x05
    DOUT_CTRL = 0x06
    CONNECT_ACK = 0x11
    SUBSCRIBE_ACK = 0x13
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


def sensor_type(sensor: str | int) -> MsgType:
    """The message id of a sensor given by name (``"adc"``) or id."""
    if isinstance(sensor, str):
        try:
            return SENSORS[sensor.lower()]
        except KeyError:
            raise ProtocolError(f"unknown ros4mat sensor {sensor!r}") from None
    return MsgType(sensor)


# ------------------------------------------------------------------------------ declarations

Header = cs.Struct(
    "type" / cs.Int8sl,
    "error" / cs.Int8sl,
    "client_id" / cs.Int32ul,
    "size" / cs.Int32ul,
    "uncompress_size" / cs.Int32ul,
    "compress_size" / cs.Int32ul,
    "compression_type" / cs.Int8sl,
    "packet_timestamp" / cs.Float64l,
)
"""``msgHeader`` (27 B). ``size`` counts records (1 for a request with a body)."""

Connect = cs.Struct("protocol_version" / cs.Int8sl, "compression" / cs.Int8sl)
"""``msgConnect`` (2 B): protocol version 3, compression 0/1 (zlib on every data reply)."""

Subscribe = cs.Struct(
    "sensor" / cs.Int8ul,
    "silent" / cs.Int8sl,
    "buffer_size" / cs.Int32ul,
    "params_size" / cs.Int32ul,
)
"""``msgSubscribe`` (10 B); ``params_size`` bytes of the sensor's params follow."""

ParamsAdc = cs.Struct(
    "freq_acquisition" / cs.Int16ul, "freq_send" / cs.Int16ul, "channels" / cs.Int8ul
)
"""``paramsAdc`` (5 B); ``channels`` is a bit mask (a C ``char``, read unsigned here)."""
ParamsImu = cs.Struct("freq_acquisition" / cs.Int16ul, "freq_send" / cs.Int16ul)
ParamsGps = cs.Struct("freq_acquisition" / cs.Int16ul, "freq_send" / cs.Int16ul)
ParamsHokuyo = cs.Struct("freq_acquisition" / cs.Int16ul)
ParamsComputer = cs.Struct("freq_acquisition" / cs.Int16ul)
ParamsBattery = cs.Struct("freq_acquisition" / cs.Int16ul, "freq_send" / cs.Int16ul)
"""robocli's own (4 B), shaped like the IMU/GPS params."""
ParamsCamera = cs.Struct(
    "fps" / cs.Int16ul,
    "width" / cs.Int16ul,
    "height" / cs.Int16ul,
    "id" / cs.Int8ul,
    "compression" / cs.Int8ul,
    "exposure" / cs.Int16sl,
    "use_roi" / cs.Int8ul,
    "roi" / cs.Array(4, cs.Int16ul),
)
"""``paramsCamera`` (19 B); ``compression`` 0 = raw, 1..100 = JPEG quality."""
ParamsStereo = cs.Struct(
    "fps" / cs.Int16ul,
    "width" / cs.Int16ul,
    "height" / cs.Int16ul,
    "id_left" / cs.Int8ul,
    "id_right" / cs.Int8ul,
    "compression" / cs.Int8ul,
    "exposure_left" / cs.Int16sl,
    "exposure_right" / cs.Int16sl,
    "use_roi" / cs.Int8ul,
    "roi_left" / cs.Array(4, cs.Int16ul),
    "roi_right" / cs.Array(4, cs.Int16ul),
)
"""``paramsStereoCam`` (30 B)."""
ParamsKinect = cs.Struct(
    "fps_rgb" / cs.Int16ul,
    "width_rgb" / cs.Int16ul,
    "height_rgb" / cs.Int16ul,
    "send_rgb" / cs.Int8ul,
    "id" / cs.Int8ul,
    "send_depth" / cs.Int8ul,
    "fps_depth" / cs.Int16ul,
    "compression_rgb" / cs.Int8ul,
    "use_roi_depth" / cs.Int8ul,
    "roi_depth" / cs.Array(4, cs.Int16ul),
    "use_roi_rgb" / cs.Int8ul,
    "roi_rgb" / cs.Array(4, cs.Int16ul),
)
"""``paramsKinect`` (30 B)."""

PARAMS: dict[int, Any] = {
    MsgType.ADC: ParamsAdc,
    MsgType.IMU: ParamsImu,
    MsgType.BATTERY: ParamsBattery,
    MsgType.GPS: ParamsGps,
    MsgType.WEBCAM: ParamsCamera,
    MsgType.COMPUTER: ParamsComputer,
    MsgType.HOKUYO: ParamsHokuyo,
    MsgType.KINECT_DEPTH: ParamsKinect,
    MsgType.KINECT: ParamsKinect,
    MsgType.WEBCAM_STEREO: ParamsStereo,
}
"""Sensor id -> subscribe params declaration."""


def _params_size(this: Any) -> int:
    params = this.params
    if params is None:
        return 0
    if isinstance(params, (bytes, bytearray)):
        return len(params)
    decl = PARAMS.get(this.sensor)
    if decl is None:
        raise ProtocolError(f"no params declaration for sensor {this.sensor}: pass bytes")
    return int(decl.sizeof())


_PARAMS_CASES: dict[Any, Any] = {int(k): v for k, v in PARAMS.items()}
_PARAMS_CASES["none"] = cs.Pass


def _params_key(this: Any) -> Any:
    if this.params_size == 0:
        return "none"
    decl = PARAMS.get(this.sensor)
    if decl is not None and decl.sizeof() == this.params_size:
        return int(this.sensor)
    return "raw"


SubscribeRequest = cs.Struct(
    "sensor" / cs.Int8ul,
    "silent" / cs.Int8sl,
    "buffer_size" / cs.Int32ul,
    "params_size" / cs.Rebuild(cs.Int32ul, _params_size),
    "params"
    / cs.FixedSized(
        cs.this.params_size,
        cs.Switch(
            _params_key,
            _PARAMS_CASES,
            default=cs.GreedyBytes,
        ),
    ),
)
"""SUBSCRIBE body: :data:`Subscribe` + params (``None`` for a silent subscribe)."""

Unsubscribe = cs.Struct("sensor" / cs.Int8ul)
"""``msgUnsubscribe`` (1 B)."""

SerialCmd = cs.Struct(
    "port_length" / cs.Int32ul,
    "speed" / cs.Int32ul,
    "parity" / cs.Int8ul,
    "stop_bits" / cs.Int8ul,
    "send_length" / cs.Int32ul,
    "read_length" / cs.Int32ul,
    "read_timeout_sec" / cs.Int16sl,
    "read_timeout_usec" / cs.Int32ul,
    "close_after" / cs.Int8ul,
)
"""``msgSerialCmd`` (25 B). ``parity``/``close_after`` are C ``bool`` (1 byte)."""

SerialCmdRequest = cs.Struct(
    "cmd" / SerialCmd,
    "port" / cs.Bytes(cs.this.cmd.port_length),
    "data" / cs.Bytes(cs.this.cmd.send_length),
)
"""SERIAL_CMD body: :data:`SerialCmd` + port name bytes + bytes to send."""

SerialAns = cs.Struct("status" / cs.Int8sl, "data_length" / cs.Int32ul)
"""``msgSerialAns`` (5 B); ``data_length`` bytes follow."""

SerialAnsReply = cs.Struct("ans" / SerialAns, "data" / cs.Bytes(cs.this.ans.data_length))

DigitalOut = cs.Struct("d0" / cs.Int8sl, "d1" / cs.Int8sl, "d2" / cs.Int8sl, "d3" / cs.Int8sl)
"""``msgDigitalOut`` (4 B): DATAQ digital outputs D0..D3."""

Adc = cs.Struct("channels" / cs.Array(8, cs.Float32l), "t" / cs.Float64l)
"""``msgAdc`` (40 B): 8 channels in volts + acquisition time."""

Imu = cs.Struct(
    "acc" / cs.Array(3, cs.Float32l),
    "gyro" / cs.Array(3, cs.Float32l),
    "mag" / cs.Array(3, cs.Float32l),
    "t" / cs.Float64l,
)
"""``msgImu`` (44 B): acceleration (g), rotation rate (deg/s), magnetic field (uT)."""

Battery = cs.Struct(
    "vtotal" / cs.Float32l,
    "current" / cs.Float32l,
    "n_cells" / cs.Int8ul,
    "vcell" / cs.Array(BATTERY_MAX_CELLS, cs.Float32l),
    "state" / cs.Int8ul,
    "state_of_charge" / cs.Float32l,
    "t" / cs.Float64l,
)
"""robocli's battery record (54 B), see the module docstring."""

Gps = cs.Struct(
    "state" / cs.Int8sl,
    "latitude" / cs.Float32l,
    "longitude" / cs.Float32l,
    "altitude" / cs.Float32l,
    "speed" / cs.Float32l,
    "track" / cs.Float32l,
    "climb" / cs.Float32l,
    "t" / cs.Float64l,
)
"""``msgGps`` (33 B): state (:class:`GpsState`), degrees, m, horizontal speed/angle, climb."""

Cam = cs.Struct(
    "width" / cs.Int32ul,
    "height" / cs.Int32ul,
    "channels" / cs.Int8ul,
    "size_data" / cs.Int32ul,
    "compression" / cs.Int8sl,
    "t" / cs.Float64l,
)
"""``msgCam`` (22 B); ``size_data`` bytes of image (RGB24 raw or JPEG) follow later."""

Computer = cs.Struct(
    "state" / cs.Int8sl,
    "cpu_temperature" / cs.Float32l,
    "unix_load" / cs.Array(3, cs.Float32l),
    "cpu_load" / cs.Array(7, cs.Float32l),
    "memory" / cs.Array(3, cs.Int32ul),
    "t" / cs.Float64l,
)
"""``msgComputer`` (65 B): cpu_load = user, sys, nice, idle, iowait, hirq, sirq;
memory = used, free, buffers."""

Hokuyo = cs.Struct(
    "angle_min" / cs.Float32l,
    "angle_max" / cs.Float32l,
    "angle_increment" / cs.Float32l,
    "time_increment" / cs.Float32l,
    "range_min" / cs.Float32l,
    "range_max" / cs.Float32l,
    "t" / cs.Float64l,
    "size_data" / cs.Int32ul,
)
"""``msgHokuyo`` (36 B); ``size_data`` bytes (float32 ranges) follow later."""

Kinect = cs.Struct("rgb" / Cam, "depth" / Cam)
"""``msgKinect`` (44 B): RGB and depth image infos sharing one timestamp."""

RECORDS: dict[int, Any] = {
    MsgType.ADC: Adc,
    MsgType.IMU: Imu,
    MsgType.BATTERY: Battery,
    MsgType.GPS: Gps,
    MsgType.COMPUTER: Computer,
}
"""Sensors whose data reply is ``size`` fixed-size records and nothing else."""

INFO_RECORDS: dict[int, Any] = {
    MsgType.WEBCAM: Cam,
    MsgType.HOKUYO: Hokuyo,
    MsgType.KINECT: Kinect,
    MsgType.KINECT_DEPTH: Kinect,
    MsgType.WEBCAM_STEREO: Cam,
}
"""Sensors whose records are followed by variable-size blobs: the fixed info record."""


def _blob_size(this: Any) -> int:
    return int(this.infos[this._index].size_data)


CameraData = cs.Struct(
    "infos" / cs.Array(cs.this._.size, Cam),
    "images" / cs.Array(cs.this._.size, cs.Bytes(_blob_size)),
)
"""WEBCAM reply: ``size`` :data:`Cam` infos, then ``size`` image blobs."""
StereoData = cs.Struct(
    "infos" / cs.Array(cs.this._.size * 2, Cam),
    "images" / cs.Array(cs.this._.size * 2, cs.Bytes(_blob_size)),
)
"""WEBCAM_STEREO reply: 2N infos (left, right interleaved), then 2N blobs in that order."""
KinectData = cs.Struct(
    "infos" / cs.Array(cs.this._.size, Kinect),
    "images"
    / cs.Array(
        cs.this._.size,
        cs.Struct(
            "rgb" / cs.Bytes(lambda this: this._.infos[this._index].rgb.size_data),
            "depth" / cs.Bytes(lambda this: this._.infos[this._index].depth.size_data),
        ),
    ),
)
"""KINECT reply: N :data:`Kinect` infos, then per frame an RGB blob and a depth blob."""
HokuyoData = cs.Struct(
    "infos" / cs.Array(cs.this._.size, Hokuyo),
    "ranges"
    / cs.Array(
        cs.this._.size,
        cs.Array(lambda this: this.infos[this._index].size_data // 4, cs.Float32l),
    ),
)
"""HOKUYO reply: N :data:`Hokuyo` infos, then N float32 range arrays (``size_data`` bytes)."""

Packet = cs.Struct(
    "header" / Header,
    "body" / cs.Bytes(lambda this: body_length(this.header)),
)
"""A whole packet with its body as bytes (compressed or error text included)."""

STRUCT_SIZES: dict[str, int] = {
    "msgHeader": 27,
    "msgConnect": 2,
    "msgSubscribe": 10,
    "paramsAdc": 5,
    "paramsImu": 4,
    "paramsGps": 4,
    "paramsHokuyo": 2,
    "paramsComputer": 2,
    "paramsCamera": 19,
    "paramsStereoCam": 30,
    "paramsKinect": 30,
    "msgUnsubscribe": 1,
    "msgSerialCmd": 25,
    "msgSerialAns": 5,
    "msgDigitalOut": 4,
    "msgAdc": 40,
    "msgImu": 44,
    "msgGps": 33,
    "msgCam": 22,
    "msgComputer": 65,
    "msgHokuyo": 36,
    "msgKinect": 44,
    "msgBattery": 54,
}
"""Original struct names -> sizes (``msgBattery`` is robocli's own)."""

DECLARATIONS: dict[str, Any] = {
    "msgHeader": Header,
    "msgConnect": Connect,
    "msgSubscribe": Subscribe,
    "paramsAdc": ParamsAdc,
    "paramsImu": ParamsImu,
    "paramsGps": ParamsGps,
    "paramsHokuyo": ParamsHokuyo,
    "paramsComputer": ParamsComputer,
    "paramsCamera": ParamsCamera,
    "paramsStereoCam": ParamsStereo,
    "paramsKinect": ParamsKinect,
    "msgUnsubscribe": Unsubscribe,
    "msgSerialCmd": SerialCmd,
    "msgSerialAns": SerialAns,
    "msgDigitalOut": DigitalOut,
    "msgAdc": Adc,
    "msgImu": Imu,
    "msgGps": Gps,
    "msgCam": Cam,
    "msgComputer": Computer,
    "msgHokuyo": Hokuyo,
    "msgKinect": Kinect,
    "msgBattery": Battery,
}
"""Original struct names -> declarations."""

REQUEST_BODIES: dict[int, Any] = {
    MsgType.CONNECT: Connect,
    MsgType.SUBSCRIBE: SubscribeRequest,
    MsgType.UNSUBSCRIBE: Unsubscribe,
    MsgType.SERIAL_CMD: SerialCmdRequest,
    MsgType.DOUT_CTRL: DigitalOut,
}
"""Request ids whose body is declared (QUIT and data pulls have none)."""


# ------------------------------------------------------------------------------ NumPy views

_NUMPY_FORMATS = {
    "b": "i1",
    "B": "u1",
    "h": "i2",
    "H": "u2",
    "i": "i4",
    "I": "u4",
    "l": "i4",
    "L": "u4",
    "q": "i8",
    "Q": "u8",
    "e": "f2",
    "f": "f4",
    "d": "f8",
}


def _numpy_format(subcon: Any, path: str) -> Any:
    """dtype spec of one fixed-size field: a primitive, an Array of them, or a Struct."""
    if isinstance(subcon, cs.Renamed):
        return _numpy_format(subcon.subcon, path)
    if isinstance(subcon, cs.FormatField):
        order, code = subcon.fmtstr[0], subcon.fmtstr[1:]
        if order not in "<>" or code not in _NUMPY_FORMATS:
            raise TypeError(f"{path}: unsupported format {subcon.fmtstr!r}")
        return np.dtype(order + _NUMPY_FORMATS[code])
    if isinstance(subcon, cs.Array) and isinstance(subcon.count, int):
        return (_numpy_format(subcon.subcon, path), (subcon.count,))
    if isinstance(subcon, cs.Struct):
        return struct_dtype(subcon, path)
    raise TypeError(f"{path}: {type(subcon).__name__} has no fixed NumPy layout")


def struct_dtype(decl: Any, path: str = "struct") -> np.dtype[Any]:
    """A packed NumPy structured dtype with the same layout as a ``construct`` Struct.

    Only named fixed-size primitive fields, fixed-count Arrays of them and nested Structs
    are supported (``TypeError`` otherwise). ``dtype.itemsize == decl.sizeof()``.
    """
    fields: list[Any] = []
    for sub in decl.subcons:
        if not sub.name:
            raise TypeError(f"{path}: unnamed field {sub!r}")
        fmt = _numpy_format(sub, f"{path}.{sub.name}")
        if isinstance(fmt, tuple):
            fields.append((sub.name, fmt[0], fmt[1]))
        else:
            fields.append((sub.name, fmt))
    dtype = np.dtype(fields)  # a list of fields gives a packed dtype
    if dtype.itemsize != decl.sizeof():
        raise TypeError(f"{path}: dtype of {dtype.itemsize} bytes != sizeof {decl.sizeof()}")
    return dtype


_DTYPE_CACHE: dict[int, np.dtype[Any]] = {}


def record_dtype(sensor: str | int) -> np.dtype[Any]:
    """The NumPy dtype of one fixed-size record of a sensor, derived from its declaration.

    ADC, IMU, GPS, COMPUTER, BATTERY give the data record; WEBCAM/WEBCAM_STEREO give
    ``msgCam``, HOKUYO ``msgHokuyo`` and KINECT ``msgKinect`` (the info records that
    precede the blobs). Use with ``np.frombuffer(body, dtype=record_dtype("adc"))``.
    """
    msg_type = sensor_type(sensor)
    cached = _DTYPE_CACHE.get(msg_type)
    if cached is None:
        decl = RECORDS.get(msg_type, INFO_RECORDS.get(msg_type))
        if decl is None:
            raise ProtocolError(f"ros4mat {msg_type.name} has no fixed-size record")
        cached = struct_dtype(decl, msg_type.name)
        _DTYPE_CACHE[msg_type] = cached
    return cached


# ------------------------------------------------------------------------------ helpers


@dataclass(frozen=True)
class Message:
    """One decoded packet.

    ``body`` is ``None`` (no body), a dict (request bodies, serial answer, camera/Kinect/
    Hokuyo replies), a list of record dicts (fixed-record sensors), or ``bytes`` (anything
    undeclared). ``error_text`` is set when the header's ``error`` is non-zero.
    """

    msg_type: int
    client_id: int = 0
    size: int = 0
    body: Any = None
    error: int = 0
    compression_type: int = 0
    packet_timestamp: float = 0.0
    error_text: str | None = None


def body_length(header: Mapping[str, Any]) -> int:
    """Bytes of body following a header on the wire.

    An error packet carries ``compress_size`` bytes of text; a packet with ``size == 0``
    has no body (the server reads none); otherwise ``compress_size`` bytes follow (equal
    to ``uncompress_size`` when uncompressed). The C framer applies the same rule.
    """
    if header["error"] != 0:
        return int(header["compress_size"])
    if header["size"] == 0:
        return 0
    return int(header["compress_size"])


def encode_packet(
    msg_type: int,
    payload: bytes = b"",
    *,
    client_id: int = 0,
    size: int | None = None,
    error: int = 0,
    compress: bool = False,
    packet_timestamp: float = 0.0,
) -> bytes:
    """One whole packet around an already-serialised ``payload``.

    ``size`` defaults to 1 when there is a payload, else 0 (what the original client sends
    with requests). ``compress`` zlib-deflates the payload (RFC 1950, default level).
    """
    payload = bytes(payload)
    if size == 0 and payload and error == 0:
        raise ProtocolError("a ros4mat packet with size 0 cannot carry a body")
    wire = zlib.compress(payload) if compress and payload else payload
    header = {
        "type": int(msg_type),
        "error": error,
        "client_id": client_id,
        "size": (1 if payload else 0) if size is None else size,
        "uncompress_size": len(payload),
        "compress_size": len(wire),
        "compression_type": Compression.ZLIB if compress and payload else Compression.NONE,
        "packet_timestamp": packet_timestamp,
    }
    try:
        data: bytes = Header.build(header) + wire
    except cs.ConstructError as exc:
        raise ProtocolError(f"cannot encode ros4mat header: {exc}") from exc
    return data


def encode_request(
    msg_type: int | str, body: Mapping[str, Any] | bytes | None = None, *, client_id: int = 0
) -> bytes:
    """A client request as the original client sends it.

    ``msg_type`` is a :class:`MsgType` or a sensor name (a data pull, header only).
    ``body`` is a dict of the request's fields (CONNECT, SUBSCRIBE, UNSUBSCRIBE, SERIAL_CMD,
    DOUT_CTRL) or raw bytes; ``None`` for QUIT and data pulls. For SUBSCRIBE, ``params`` is a
    dict of the sensor's params, raw bytes, or ``None`` (silent subscribe); ``params_size``
    is computed.
    """
    kind = sensor_type(msg_type) if isinstance(msg_type, str) else MsgType(msg_type)
    if body is None:
        payload = b""
    elif isinstance(body, (bytes, bytearray)):
        payload = bytes(body)
    else:
        decl = REQUEST_BODIES.get(kind)
        if decl is None:
            raise ProtocolError(f"ros4mat {kind.name} takes no body")
        values = dict(body)
        if kind == MsgType.SUBSCRIBE:
            values.setdefault("params", None)
            values["sensor"] = sensor_type(values["sensor"])
        elif kind == MsgType.UNSUBSCRIBE:
            values["sensor"] = sensor_type(values["sensor"])
        try:
            payload = decl.build(values)
        except (cs.ConstructError, KeyError) as exc:
            raise ProtocolError(f"cannot encode ros4mat {kind.name}: {exc}") from exc
    return encode_packet(kind, payload, client_id=client_id)


def encode_records(
    msg_type: int | str,
    records: Sequence[Mapping[str, Any]],
    *,
    client_id: int = 0,
    packet_timestamp: float = 0.0,
    compress: bool = False,
) -> bytes:
    """A data reply of fixed-size records (ADC, IMU, BATTERY, GPS, COMPUTER)."""
    kind = sensor_type(msg_type)
    decl = RECORDS.get(kind)
    if decl is None:
        raise ProtocolError(f"ros4mat {kind.name} replies are not fixed-size records")
    try:
        payload = b"".join(decl.build(r) for r in records)
    except (cs.ConstructError, KeyError) as exc:
        raise ProtocolError(f"cannot encode ros4mat {kind.name} record: {exc}") from exc
    return encode_packet(
        kind,
        payload,
        client_id=client_id,
        size=len(records),
        compress=compress,
        packet_timestamp=packet_timestamp,
    )


def encode_error(msg_type: int, text: str, *, client_id: int = 0) -> bytes:
    """An error reply: header with ``error = 1`` and a NUL-terminated ASCII text."""
    raw = text.encode("ascii", "replace") + b"\0"
    header = {
        "type": int(msg_type),
        "error": 1,
        "client_id": client_id,
        "size": 0,
        "uncompress_size": len(raw),
        "compress_size": len(raw),
        "compression_type": Compression.NONE,
        "packet_timestamp": 0.0,
    }
    data: bytes = Header.build(header) + raw
    return data


def _decode_body(kind: int, size: int, payload: bytes) -> Any:
    if not payload:
        return None
    if kind in REQUEST_BODIES:
        decl = REQUEST_BODIES[kind]
        return plain(decl.parse(payload))
    if kind in RECORDS:
        rec = RECORDS[kind]
        if len(payload) != size * rec.sizeof():
            raise ProtocolError(
                f"ros4mat {MsgType(kind).name}: {len(payload)} body bytes for {size} records "
                f"of {rec.sizeof()}"
            )
        return plain(cs.Array(size, rec).parse(payload))
    complex_bodies: dict[int, Any] = {
        MsgType.WEBCAM: CameraData,
        MsgType.WEBCAM_STEREO: StereoData,
        MsgType.KINECT: KinectData,
        MsgType.KINECT_DEPTH: KinectData,
        MsgType.HOKUYO: HokuyoData,
        MsgType.SERIAL_ANS: SerialAnsReply,
    }
    decl = complex_bodies.get(kind)
    if decl is None:
        return payload
    if kind == MsgType.SERIAL_ANS:
        return plain(decl.parse(payload))
    return plain(decl.parse(payload, size=size))


def decode(frame: bytes) -> Message:
    """Decode one whole packet (header + body), inflating a zlib body.

    Raises :class:`FramingError` when the frame's length does not match its header and
    :class:`ProtocolError` when the body does not match its declaration.
    """
    frame = bytes(frame)
    if len(frame) < HEADER_SIZE:
        raise FramingError(f"ros4mat packet of {len(frame)} bytes is shorter than its header")
    header = Header.parse(frame[:HEADER_SIZE])
    n = body_length(header)
    if n > MAX_BODY_SIZE:
        raise FramingError(f"ros4mat body of {n} bytes exceeds {MAX_BODY_SIZE}")
    if len(frame) != HEADER_SIZE + n:
        raise FramingError(
            f"ros4mat header announces {n} body bytes, the frame has {len(frame) - HEADER_SIZE}"
        )
    payload = frame[HEADER_SIZE:]
    common: dict[str, Any] = {
        "msg_type": _enum_type(header.type),
        "client_id": header.client_id,
        "size": header.size,
        "error": header.error,
        "compression_type": header.compression_type,
        "packet_timestamp": header.packet_timestamp,
    }
    if header.error != 0:
        text = payload.split(b"\0", 1)[0].decode("ascii", "replace")
        return Message(body=None, error_text=text, **common)
    if header.compression_type == Compression.ZLIB and payload:
        try:
            payload = zlib.decompress(payload)
        except zlib.error as exc:
            raise ProtocolError(f"ros4mat zlib body does not inflate: {exc}") from exc
        if len(payload) != header.uncompress_size:
            raise ProtocolError(
                f"ros4mat body inflated to {len(payload)} bytes, header says "
                f"{header.uncompress_size}"
            )
    elif header.compression_type != Compression.NONE:
        raise ProtocolError(f"ros4mat compression type {header.compression_type} unknown")
    elif header.uncompress_size != header.compress_size and payload:
        raise ProtocolError(
            f"uncompressed ros4mat body with uncompress_size {header.uncompress_size} != "
            f"compress_size {header.compress_size}"
        )
    try:
        body = _decode_body(header.type, header.size, payload)
    except cs.ConstructError as exc:
        raise ProtocolError(f"ros4mat {common['msg_type']!r} body: {exc}") from exc
    return Message(body=body, **common)


def _enum_type(value: int) -> int:
    try:
        return MsgType(value)
    except ValueError:
        return value


def adc_freq_send_default(freq: int) -> int:
    """The original client's default ``freqSend`` for a capture rate (not clamped)."""
    return math.floor(freq / 4 + 10)


__all__ = [
    "BATTERY_MAX_CELLS",
    "DECLARATIONS",
    "HEADER_SIZE",
    "INFO_RECORDS",
    "MAX_BODY_SIZE",
    "PARAMS",
    "PORT",
    "PROTOCOL_VERSION",
    "RECORDS",
    "REQUEST_BODIES",
    "SENSORS",
    "STRUCT_SIZES",
    "Adc",
    "Battery",
    "BatteryState",
    "Cam",
    "CameraData",
    "Compression",
    "Computer",
    "ComputerState",
    "Connect",
    "DigitalOut",
    "GpsState",
    "Gps",
    "Header",
    "Hokuyo",
    "HokuyoData",
    "Imu",
    "Kinect",
    "KinectData",
    "Message",
    "MsgType",
    "Packet",
    "ParamsAdc",
    "ParamsBattery",
    "ParamsCamera",
    "ParamsComputer",
    "ParamsGps",
    "ParamsHokuyo",
    "ParamsImu",
    "ParamsKinect",
    "ParamsStereo",
    "SerialAns",
    "SerialAnsReply",
    "SerialCmd",
    "SerialCmdRequest",
    "SerialStatus",
    "StereoData",
    "Subscribe",
    "SubscribeRequest",
    "Unsubscribe",
    "adc_freq_send_default",
    "body_length",
    "decode",
    "encode_error",
    "encode_packet",
    "encode_records",
    "encode_request",
    "plain",
    "record_dtype",
    "sensor_type",
    "struct_dtype",
]
