"""Reading a ROS 2 bag's messages as robocli's readers read a recording's JSON.

:func:`decode` turns one CDR message into a plain dict (:func:`~robocli.ros2.types.plain`)
with what robocli's readers (``plot``, ``export``) expect of every message: a
``timestamp`` (``{"sec", "nsec"}``, from the header's stamp when the type has one), byte
arrays as base64 text (as robocli's JSON holds image data), and no number without a value
(NaN and infinities left out, as robocli's JSON leaves them out). The types robocli draws
get the fields of the robocli schema they correspond to (:data:`VIEWS`), beside their own:

- ``sensor_msgs/msg/LaserScan``: ``start_angle``, ``end_angle``, ``frame_id``, an identity
  ``pose``, and ``ranges`` with 0 where ROS says no return (+inf, REP 117);
- ``nav_msgs/msg/Odometry`` and ``geometry_msgs/msg/PoseStamped``: ``pose`` (position and
  orientation) and ``frame_id``;
- ``sensor_msgs/msg/JointState``: its ``name``, ``position``... are robocli's already.

(An export writes the message's own fields: ``decode(..., view=False)``.) A reader names
such a channel by :func:`view_schema` to pick its figure or log format.
"""

from __future__ import annotations

import base64
import math
from typing import Any

from robocli.ros2 import types as T

__all__ = ["VIEWS", "decode", "view_schema"]

#: The robocli schema a ROS 2 type is read as (see the module docstring).
VIEWS = {
    "sensor_msgs/msg/LaserScan": "foxglove.LaserScan",
    "nav_msgs/msg/Odometry": "foxglove.PoseInFrame",
    "geometry_msgs/msg/PoseStamped": "foxglove.PoseInFrame",
    "sensor_msgs/msg/JointState": "robocli.JointState",
}


def view_schema(msgtype: str) -> str:
    """The robocli schema ``msgtype`` is read as, else ``msgtype`` itself."""
    return VIEWS.get(msgtype, msgtype)


def decode(msgtype: str, data: bytes | memoryview, view: bool = True) -> dict[str, Any]:
    """One CDR message of ``msgtype`` as a robocli reader's dict (see the module
    docstring); without ``view``, the message's own fields only (and ``timestamp``), as an
    export writes them. Raises :class:`~robocli.errors.RobocliError` for bytes that do not
    decode."""
    raw = T.plain(T.deserialize(data, msgtype))
    if view and msgtype == "sensor_msgs/msg/LaserScan":  # no return (+-inf, NaN): robocli's 0
        raw["ranges"] = [r if math.isfinite(r) else 0.0 for r in raw["ranges"]]
    msg = _clean(raw)
    assert isinstance(msg, dict)
    header = msg.get("header")
    stamp = header.get("stamp") if isinstance(header, dict) else msg.get("stamp")
    if isinstance(stamp, dict):
        msg = {"timestamp": {"sec": stamp.get("sec", 0), "nsec": stamp.get("nanosec", 0)},
               **msg}  # fmt: skip
    frame_id = header.get("frame_id", "") if isinstance(header, dict) else ""
    if not view:
        return msg
    if msgtype == "sensor_msgs/msg/LaserScan":
        msg.update(
            start_angle=msg.get("angle_min"),
            end_angle=msg.get("angle_max"),
            frame_id=frame_id,
            pose=_IDENTITY,
        )
    elif msgtype == "nav_msgs/msg/Odometry":
        msg.update(frame_id=frame_id, pose=msg.get("pose", {}).get("pose", {}))
    elif msgtype == "geometry_msgs/msg/PoseStamped":
        msg["frame_id"] = frame_id
    return msg


_IDENTITY = {"position": {"x": 0.0, "y": 0.0, "z": 0.0},
             "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}  # fmt: skip


def _clean(value: Any) -> Any:
    """Bytes as base64 text; a non-finite number left out, and a list holding one (a list
    cannot have a hole), as robocli's JSON does (None: left out)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, bytes):
        return base64.b64encode(value).decode("ascii")
    if isinstance(value, dict):
        out = {k: _clean(v) for k, v in value.items()}
        return {k: v for k, v in out.items() if v is not None}
    if isinstance(value, list):
        items = [_clean(v) for v in value]
        return None if any(v is None for v in items) else items
    return value
