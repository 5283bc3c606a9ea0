"""ros4mat message declarations and tables (protocol version 3); the ids, sizes and
sensor names are :mod:`.ids`'s.

Part of :mod:`robocli.protocols.ros4mat` (import from there; its docstring has the facts).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import construct as cs

from robocli.errors import ProtocolError
from robocli.protocols.ros4mat.ids import (
    BATTERY_MAX_CELLS,
    MsgType,
)
from robocli.protocols.ros4mat.stream import SerialOpen

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
    MsgType.SERIAL_OPEN: SerialOpen,
}
"""Request ids whose body is declared (QUIT and data pulls have none)."""
