"""The JSON schemas of robocli's recordings: Foxglove's well-known ones, and robocli's own.

A channel whose schema is named ``foxglove.PoseInFrame``, ``foxglove.FrameTransform(s)``,
``foxglove.LaserScan``, ``foxglove.CompressedImage``, ``foxglove.RawImage`` or
``foxglove.LocationFix`` (schema encoding ``jsonschema``, message encoding ``json``) is shown
by Foxglove's panels without a plugin. The field names and types here are those Foxglove
documents for each schema (docs.foxglove.dev, "Message schemas"); the schema documents are
written for robocli and list only the fields robocli fills. Binary fields (image data) are
base64 strings with ``"contentEncoding": "base64"``, as Foxglove's JSON encoding wants.

Data with no well-known schema gets a ``robocli.*`` schema that names every field with its
unit: joint states shaped like ``sensor_msgs/JointState``, IMU like ``sensor_msgs/Imu``, ADC,
battery, the Pioneer's state, the arm's status, the hub's system information, and the raw
frames of every link (``robocli.RawFrame``). Units are SI
(m, rad, s, m/s, rad/s, V, A, T) unless a field's description says otherwise.

Every schema stays inside the JSON-schema subset Foxglove and Lichtblick read: one ``type``
string per field, no ``["number", "null"]`` union, no ``null``. What robocli does not know
is left out of the message (a plot shows a gap there), never written as null: a number
without a value (NaN, an infinity: see :func:`robocli.io.record.links.json_text`), a
controller's clock it did not send, a status flag the arm reports as unknown. So a
robocli schema requires only the fields that always have a value; a number, or a list or
object of numbers, may be absent. A list cannot have a hole: the Pioneer's ``sonar`` is 0
for a sonar that has not reported yet, and ``sonar_known`` says which have.

No I/O here: :data:`SCHEMAS` maps a schema name to its JSON document, and the builders return
plain dicts ready for :func:`json.dumps`.
"""

from __future__ import annotations

import json
import math
from typing import Any

__all__ = [
    "FOXGLOVE",
    "ROS",
    "SCHEMAS",
    "compressed_image",
    "frame_transform",
    "laser_scan",
    "location_fix",
    "pose",
    "quaternion_z",
    "raw_image",
    "schema_bytes",
    "stamp",
]

# ---------------------------------------------------------------------- building blocks


def _number(description: str) -> dict[str, Any]:
    return {"type": "number", "description": description}


def _integer(description: str) -> dict[str, Any]:
    return {"type": "integer", "description": description}


def _boolean(description: str) -> dict[str, Any]:
    return {"type": "boolean", "description": description}


def _string(description: str) -> dict[str, Any]:
    return {"type": "string", "description": description}


def _numbers(description: str) -> dict[str, Any]:
    return {"type": "array", "items": {"type": "number"}, "description": description}


def _object(title: str, description: str, properties: dict[str, Any],
            required: tuple[str, ...] | None = None) -> dict[str, Any]:  # fmt: skip
    return {
        "title": title,
        "description": description,
        "type": "object",
        "properties": properties,
        "required": list(properties if required is None else required),
    }


_TIME = {
    "type": "object",
    "title": "time",
    "description": "Seconds and nanoseconds since the Unix epoch",
    "properties": {
        "sec": {"type": "integer", "minimum": 0},
        "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999},
    },
    "required": ["sec", "nsec"],
}


def _vector3(description: str, unit: str = "m") -> dict[str, Any]:
    return _object("foxglove.Vector3", description, {
        "x": _number(f"x, {unit}"), "y": _number(f"y, {unit}"), "z": _number(f"z, {unit}"),
    })  # fmt: skip


_QUATERNION = _object("foxglove.Quaternion", "Orientation as a unit quaternion", {
    "x": _number("x"), "y": _number("y"), "z": _number("z"), "w": _number("w"),
})  # fmt: skip

_POSE = _object("foxglove.Pose", "Position (m) and orientation in 3D space", {
    "position": _vector3("Position"), "orientation": _QUATERNION,
})  # fmt: skip


def _stamped(title: str, description: str, properties: dict[str, Any],
             required: tuple[str, ...] | None = None) -> dict[str, Any]:  # fmt: skip
    """A message whose first field is ``timestamp`` (the source's acquisition time)."""
    props = {"timestamp": dict(_TIME, description="Acquisition time (Unix epoch)")}
    props.update(properties)
    return _object(title, description, props, None if required is None else
                   ("timestamp", *required))  # fmt: skip


def _has_number(schema: dict[str, Any]) -> bool:
    """Whether a number is in ``schema`` (itself, its items or its properties)."""
    items = schema.get("items")
    return (schema.get("type") == "number" or (items is not None and _has_number(items))
            or any(_has_number(p) for p in schema.get("properties", {}).values()))  # fmt: skip


def _robocli(title: str, description: str, properties: dict[str, Any],
             unknown: tuple[str, ...] = ()) -> dict[str, Any]:  # fmt: skip
    """A robocli message (stamped): every field required but those that may be left out,
    which are those holding a number and those named in ``unknown`` (see the module
    docstring)."""
    required = tuple(k for k, v in properties.items() if k not in unknown and not _has_number(v))
    return _stamped(title, description, properties, required)


# ---------------------------------------------------------------------- Foxglove's schemas

_FRAME_TRANSFORM = _stamped(
    "foxglove.FrameTransform",
    "Position and orientation of a child frame in its parent frame",
    {
        "parent_frame_id": _string("Parent frame"),
        "child_frame_id": _string("Child frame"),
        "translation": _vector3("Origin of the child frame in the parent frame"),
        "rotation": _QUATERNION,
    },
)

_BASE64 = {"type": "string", "contentEncoding": "base64"}

FOXGLOVE: dict[str, dict[str, Any]] = {
    "foxglove.PoseInFrame": _stamped(
        "foxglove.PoseInFrame",
        "A pose in a frame of reference",
        {"frame_id": _string("Frame of reference of the pose"), "pose": _POSE},
    ),
    "foxglove.FrameTransform": _FRAME_TRANSFORM,
    "foxglove.FrameTransforms": _object(
        "foxglove.FrameTransforms",
        "Several frame transforms at once",
        {
            "transforms": {
                "type": "array",
                "items": _FRAME_TRANSFORM,
                "description": "The transforms",
            }
        },
    ),
    "foxglove.LaserScan": _stamped(
        "foxglove.LaserScan",
        "A planar scan: ranges at equally spaced bearings from start_angle to end_angle "
        "(counter-clockwise about z, 0 along +x of the pose); robocli writes 0 for a bearing "
        "with no return",
        {
            "frame_id": _string("Frame of reference"),
            "pose": _POSE,
            "start_angle": _number("Bearing of the first range, rad"),
            "end_angle": _number("Bearing of the last range, rad"),
            "ranges": _numbers("Distances, m (0: no return)"),
            "intensities": _numbers("Intensity of each return (reflectance), or empty"),
        },
    ),
    "foxglove.CompressedImage": _stamped(
        "foxglove.CompressedImage",
        "A compressed image",
        {
            "frame_id": _string("Camera frame"),
            "data": dict(_BASE64, description="Compressed image bytes, base64"),
            "format": _string("Image format: jpeg or png"),
        },
    ),
    "foxglove.RawImage": _stamped(
        "foxglove.RawImage",
        "An uncompressed image",
        {
            "frame_id": _string("Camera frame"),
            "width": _integer("Width, pixels"),
            "height": _integer("Height, pixels"),
            "encoding": _string("Pixel layout: rgb8, or mono16 (depth in mm, little-endian)"),
            "step": _integer("Bytes per row"),
            "data": dict(_BASE64, description="Pixel bytes, row by row, base64"),
        },
    ),
    "foxglove.LocationFix": _stamped(
        "foxglove.LocationFix",
        "A satellite navigation fix",
        {
            "frame_id": _string("Frame of the receiver"),
            "latitude": _number("Latitude, degrees"),
            "longitude": _number("Longitude, degrees"),
            "altitude": _number("Altitude, m"),
            "position_covariance": {
                "type": "array",
                "items": {"type": "number"},
                "minItems": 9,
                "maxItems": 9,
                "description": "ENU covariance, m^2, row-major",
            },
            "position_covariance_type": _integer(
                "0 unknown, 1 approximated, 2 diagonal known, 3 known"
            ),
        },
    ),
}

# ---------------------------------------------------------------------- robocli's schemas

_XYZ_ACCEL = _vector3("Linear acceleration", "m/s^2")
_XYZ_GYRO = _vector3("Angular velocity", "rad/s")
_XYZ_MAG = _vector3("Magnetic field", "T")

ROBOCLI: dict[str, dict[str, Any]] = {
    "robocli.pioneer.State": _robocli(
        "robocli.pioneer.State",
        "One Pioneer SIP in SI units (odometry pose unwrapped); a "
        "number without a value is left out",
        {
            "x": _number("Odometry x, m"),
            "y": _number("Odometry y, m"),
            "th": _number("Odometry heading, rad, in [-pi, pi)"),
            "v": _number("Translational velocity, m/s"),
            "w": _number("Rotational velocity, rad/s, counter-clockwise positive"),
            "left_velocity": _number("Left wheel, m/s"),
            "right_velocity": _number("Right wheel, m/s"),
            "battery": _number("Battery, V"),
            "motors_enabled": _boolean("Motors powered"),
            "estop": _boolean("Emergency stop pressed"),
            "stall_left": _boolean("Left wheel stalled"),
            "stall_right": _boolean("Right wheel stalled"),
            "bumpers_front": _integer("Front bumper switches, bit mask"),
            "bumpers_rear": _integer("Rear bumper switches, bit mask"),
            "sonar": _numbers("Latest range per sonar index, m (0: none yet, see sonar_known)"),
            "sonar_known": {
                "type": "array",
                "items": {"type": "boolean"},
                "description": "Per sonar index: it has reported a range",
            },
            "digin": _integer("Digital inputs, bit mask"),
            "digout": _integer("Digital outputs, bit mask"),
            "analog": _number("Selected analog input, V"),
            "sip_count": _integer("SIPs decoded by the recorder"),
        },
    ),
    "robocli.create.State": _robocli(
        "robocli.create.State",
        "One iRobot Create 2 stream frame in SI units (odometry pose "
        "summed from the distance and angle packets since the recording began)",
        {
            "x": _number("Odometry x, m"),
            "y": _number("Odometry y, m"),
            "th": _number("Odometry heading, rad, in [-pi, pi]"),
            "bump_left": _boolean("Left bumper pressed"),
            "bump_right": _boolean("Right bumper pressed"),
            "wheel_drop_left": _boolean("Left wheel dropped"),
            "wheel_drop_right": _boolean("Right wheel dropped"),
            "voltage": _number("Battery, V"),
            "current": _number("Battery current, A (negative: discharging)"),
            "charge": _number("Battery charge, Ah"),
            "capacity": _number("Battery capacity, Ah"),
            "charging_state": _integer("Charging state code (0: not charging)"),
            "mode": _integer("OI mode: 0 off, 1 passive, 2 safe, 3 full"),
            "frame_count": _integer("Stream frames decoded by the recorder"),
        },
    ),
    "robocli.JointState": _robocli(
        "robocli.JointState",
        "Joint positions, shaped like sensor_msgs/JointState (empty arrays: not reported)",
        {
            "name": {"type": "array", "items": {"type": "string"}, "description": "Joints"},
            "position": _numbers("Positions, rad"),
            "velocity": _numbers("Velocities, rad/s"),
            "effort": _numbers("Efforts, N m"),
            "source": _string("joint_position or joint_feedback"),
            "robot_time": _number(
                "The controller's own clock, s (JOINT_FEEDBACK; absent: not sent)"
            ),
        },
    ),
    "robocli.arm.Status": _robocli(
        "robocli.arm.Status",
        "The controller's STATUS (a flag it reports as unknown is left out)",
        {
            "drives_powered": _boolean("Drives powered"),
            "e_stopped": _boolean("Emergency stop"),
            "in_error": _boolean("In error"),
            "in_motion": _boolean("Moving"),
            "motion_possible": _boolean("Can move"),
            "mode": _string("MANUAL, AUTO or UNKNOWN"),
            "error_code": _integer("Controller error code"),
        },
        unknown=("drives_powered", "e_stopped", "in_error", "in_motion", "motion_possible"),
    ),
    "robocli.Imu": _robocli(
        "robocli.Imu",
        "One IMU sample, shaped like sensor_msgs/Imu (no orientation)",
        {
            "frame_id": _string("IMU frame"),
            "linear_acceleration": _XYZ_ACCEL,
            "angular_velocity": _XYZ_GYRO,
            "magnetic_field": _XYZ_MAG,
        },
    ),
    "robocli.Adc": _robocli(
        "robocli.Adc",
        "One sample of the hub's 8-channel ADC",
        {"channels": _numbers("Channels 0..7, V")},
    ),
    "robocli.Battery": _robocli(
        "robocli.Battery",
        "One battery sample",
        {
            "voltage": _number("Pack voltage, V"),
            "current": _number("Current, A"),
            "cells": _numbers("Cell voltages, V"),
            "state": _integer("Charge state code"),
            "state_of_charge": _number("State of charge, 0..1"),
        },
    ),
    "robocli.SysInfo": _robocli(
        "robocli.SysInfo",
        "The hub computer's load, memory and temperature",
        {
            "cpu_temperature": _number("CPU temperature, deg C (absent: no sensor)"),
            "load": _numbers("Unix load averages over 1, 5, 15 min"),
            "cpu": {
                "type": "object",
                "description": "CPU time split, %",
                "properties": {
                    k: _number(f"{k}, %")
                    for k in ("user", "sys", "nice", "idle", "iowait", "hirq", "sirq")
                },
            },
            "memory": {
                "type": "object",
                "description": "Memory, kB",
                "properties": {k: _number(f"{k}, kB") for k in ("used", "free", "buffers")},
            },
            "state": _integer("Source state code"),
        },
    ),
    "robocli.RawFrame": _robocli(
        "robocli.RawFrame",
        "One whole frame as it went over a link (framing and checksum included), base64",
        {
            "link": _string("The link's name (the topic's first part)"),
            "protocol": _string("arcos, sm-le, sm-be, ros4mat, scip2 or create-oi"),
            "direction": _string("tx: robocli sent it; rx: robocli received it"),
            "port": _string("The arm's port, motion or state (empty for other links)"),
            "data": dict(_BASE64, description="The frame's bytes, base64"),
        },
    ),
}

#: ROS messages robocli writes as JSON where a viewer knows them by their ROS name: a robot's
#: model (URDF text in ``data``) on ``/robot_description``, which the 3D panel of Foxglove
#: and Lichtblick reads from a message of schema ``std_msgs/String`` (or
#: ``std_msgs/msg/String``) only.
ROS: dict[str, dict[str, Any]] = {
    "std_msgs/String": _object(
        "std_msgs/String",
        "Text, shaped like std_msgs/String: here a robot's URDF",
        {"data": _string("The text (a robot description: URDF XML)")},
    ),
}

#: Every schema a recording may use, by name.
SCHEMAS: dict[str, dict[str, Any]] = {**FOXGLOVE, **ROBOCLI, **ROS}


def schema_bytes(name: str) -> bytes:
    """The JSON schema document of ``name``, as stored in a recording."""
    return json.dumps(SCHEMAS[name], separators=(",", ":")).encode()


# ---------------------------------------------------------------------- message builders


def stamp(ns: int) -> dict[str, int]:
    """``{"sec", "nsec"}`` of a time in Unix-epoch nanoseconds."""
    sec, nsec = divmod(ns, 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


def quaternion_z(th: float) -> dict[str, float]:
    """The quaternion of a rotation by ``th`` rad about z."""
    return {"x": 0.0, "y": 0.0, "z": math.sin(th / 2), "w": math.cos(th / 2)}


def pose(x: float = 0.0, y: float = 0.0, z: float = 0.0,
         q: dict[str, float] | None = None) -> dict[str, Any]:  # fmt: skip
    """A ``foxglove.Pose``: position (m) and orientation (identity when ``q`` is None)."""
    return {"position": {"x": x, "y": y, "z": z},
            "orientation": q or {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}  # fmt: skip


def frame_transform(ns: int, parent: str, child: str, translation: tuple[float, float, float],
                    rotation: dict[str, float]) -> dict[str, Any]:  # fmt: skip
    """A ``foxglove.FrameTransform``."""
    x, y, z = translation
    return {"timestamp": stamp(ns), "parent_frame_id": parent, "child_frame_id": child,
            "translation": {"x": x, "y": y, "z": z}, "rotation": rotation}  # fmt: skip


def laser_scan(ns: int, frame_id: str, start: float, end: float, ranges: list[float],
               intensities: list[float] | None = None) -> dict[str, Any]:  # fmt: skip
    """A ``foxglove.LaserScan`` at the frame's origin; infinite or NaN ranges become 0."""
    return {
        "timestamp": stamp(ns), "frame_id": frame_id, "pose": pose(),
        "start_angle": start, "end_angle": end,
        "ranges": [r if math.isfinite(r) else 0.0 for r in ranges],
        "intensities": list(intensities or ()),
    }  # fmt: skip


def compressed_image(ns: int, frame_id: str, data: bytes | memoryview, fmt: str = "jpeg", *,
                     raw: bool = False) -> dict[str, Any]:  # fmt: skip
    """A ``foxglove.CompressedImage`` (``data`` base64-encoded here; ``raw``: kept as the
    bytes, for a sink that takes dicts, never for JSON)."""
    return {"timestamp": stamp(ns), "frame_id": frame_id, "data": _data(data, raw),
            "format": fmt}  # fmt: skip


def raw_image(ns: int, frame_id: str, width: int, height: int, encoding: str, step: int,
              data: bytes | memoryview, *, raw: bool = False) -> dict[str, Any]:  # fmt: skip
    """A ``foxglove.RawImage`` (``data`` as in :func:`compressed_image`)."""
    return {"timestamp": stamp(ns), "frame_id": frame_id, "width": width, "height": height,
            "encoding": encoding, "step": step, "data": _data(data, raw)}  # fmt: skip


def _data(data: bytes | memoryview, raw: bool) -> str | bytes | memoryview:
    import base64

    return data if raw else base64.b64encode(data).decode("ascii")


def location_fix(ns: int, frame_id: str, latitude: float, longitude: float,
                 altitude: float) -> dict[str, Any]:  # fmt: skip
    """A ``foxglove.LocationFix`` without covariance (type 0, unknown)."""
    return {"timestamp": stamp(ns), "frame_id": frame_id, "latitude": latitude,
            "longitude": longitude, "altitude": altitude,
            "position_covariance": [0.0] * 9, "position_covariance_type": 0}  # fmt: skip
