"""ros4mat protocol version 3 (the sensor hub's wire format), declared once with ``construct``.

Facts from ``docs/protocols/ros4mat.md`` (the original project's ``exchangeStructs.h``,
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

**Serial streaming (0x07-0x09, 0x17, 0x2B) is robocli's extension**, documented in
:mod:`robocli.protocols.ros4mat.stream`; the original messages are unchanged.
"""

from __future__ import annotations

from robocli.protocols.common import plain
from robocli.protocols.ros4mat.codec import (
    DecodedPacket,
    adc_freq_send_default,
    decode,
    encode_error,
    encode_packet,
    encode_records,
    encode_request,
    inflate,
    record_dtype,
    struct_dtype,
)
from robocli.protocols.ros4mat.ids import (
    BATTERY_MAX_CELLS,
    HEADER_SIZE,
    INFLATE_STEP,
    MAX_BODY_SIZE,
    PORT,
    PROTOCOL_VERSION,
    SENSORS,
    BatteryState,
    Compression,
    ComputerState,
    GpsState,
    MsgType,
    SerialStatus,
    sensor_type,
)
from robocli.protocols.ros4mat.messages import (
    DECLARATIONS,
    INFO_RECORDS,
    PARAMS,
    RECORDS,
    REQUEST_BODIES,
    STRUCT_SIZES,
    Adc,
    Battery,
    Cam,
    CameraData,
    Computer,
    Connect,
    DigitalOut,
    Gps,
    Header,
    Hokuyo,
    HokuyoData,
    Imu,
    Kinect,
    KinectData,
    Packet,
    ParamsAdc,
    ParamsBattery,
    ParamsCamera,
    ParamsComputer,
    ParamsGps,
    ParamsHokuyo,
    ParamsImu,
    ParamsKinect,
    ParamsStereo,
    SerialAns,
    SerialAnsReply,
    SerialCmd,
    SerialCmdRequest,
    StereoData,
    Subscribe,
    SubscribeRequest,
    Unsubscribe,
    body_length,
)
from robocli.protocols.ros4mat.stream import (
    MAX_STREAM_CHUNK,
    PARITIES,
    STOP_BITS,
    SerialOpen,
    write_deadline,
)

__all__ = [
    "Adc",
    "BATTERY_MAX_CELLS",
    "Battery",
    "BatteryState",
    "Cam",
    "CameraData",
    "Compression",
    "Computer",
    "ComputerState",
    "Connect",
    "DECLARATIONS",
    "DecodedPacket",
    "DigitalOut",
    "Gps",
    "GpsState",
    "HEADER_SIZE",
    "Header",
    "Hokuyo",
    "HokuyoData",
    "INFLATE_STEP",
    "INFO_RECORDS",
    "Imu",
    "Kinect",
    "KinectData",
    "MAX_BODY_SIZE",
    "MAX_STREAM_CHUNK",
    "MsgType",
    "PARAMS",
    "PARITIES",
    "PORT",
    "PROTOCOL_VERSION",
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
    "RECORDS",
    "REQUEST_BODIES",
    "SENSORS",
    "STOP_BITS",
    "STRUCT_SIZES",
    "SerialAns",
    "SerialAnsReply",
    "SerialCmd",
    "SerialCmdRequest",
    "SerialOpen",
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
    "inflate",
    "plain",
    "record_dtype",
    "sensor_type",
    "struct_dtype",
    "write_deadline",
]
