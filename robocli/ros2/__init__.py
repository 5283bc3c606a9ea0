"""ROS 2 without ROS: robocli's samples as standard ROS 2 messages in CDR
(:mod:`.mapping`), the type store, schemas and type hashes (:mod:`.types`).

>>> from robocli.ros2 import to_ros2, type_hash, msgdef   # doctest: +SKIP
>>> for m in to_ros2("foxglove.LaserScan", "/laser/scan", scan):
...     publish(m.topic, type_hash(m.msgtype), m.data, m.t_ns)

Needs the ``rosbags`` package (``pip install 'robocli-robots[record]'``): without it, the first
call raises :class:`~.types.Ros2Unavailable`.
"""

from robocli.ros2.mapping import Mapper, Ros2Message, laser_scan_cdr, to_ros2
from robocli.ros2.types import (
    RAW_FRAME,
    Ros2Unavailable,
    deserialize,
    msgdef,
    plain,
    serialize,
    type_hash,
)

__all__ = [
    "RAW_FRAME",
    "Mapper",
    "Ros2Message",
    "Ros2Unavailable",
    "deserialize",
    "laser_scan_cdr",
    "msgdef",
    "plain",
    "serialize",
    "to_ros2",
    "type_hash",
]
