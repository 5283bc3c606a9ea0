"""The ROS 2 type store robocli serialises with: the standard messages of ROS 2 Kilted as
the ``rosbags`` package ships them, and robocli's own ``robocli_msgs/msg/RawFrame``.

``rosbags`` (pure Python, Apache-2.0) is the optional dependency (``pip install
'robocli-robots[record]'``); this module imports it on first use and says what to install when it
is missing. Everything here is pure: no I/O.

- :func:`message` builds a message object of a type (``sensor_msgs/msg/LaserScan``...);
- :func:`serialize` / :func:`deserialize`: CDR, little-endian, with the 4-byte
  encapsulation header ``00 01 00 00`` that rmw, rosbag2 and Foxglove expect;
- :func:`msgdef`: the ``ros2msg`` text an MCAP schema holds (the type, then each
  dependency after a ``====`` line, as ``ros2 bag record`` writes it);
- :func:`type_hash`: the type's ``RIHS01_<sha256 hex>`` (REP 2011), which rmw_zenoh puts in
  its keys and rosbag2 in a channel's ``topic_type_hash``;
- :func:`plain`: a deserialised message as plain dicts, lists and numbers (for readers).
"""

from __future__ import annotations

import functools
from typing import Any

from robocli.errors import RobocliError

__all__ = [
    "RAW_FRAME",
    "RAW_FRAME_MSG",
    "RAW_SCHEMA",
    "Ros2Unavailable",
    "deserialize",
    "message",
    "msgdef",
    "node_types",
    "plain",
    "serialize",
    "type_hash",
    "typestore",
]

#: robocli's message for the raw bytes of a link: one whole frame as it went over the wire
#: (framing and checksum included). ``direction``: ``tx`` (robocli sent it) or ``rx``;
#: ``protocol``: ``arcos``, ``sm-le``, ``sm-be``, ``ros4mat`` or ``scip2``; ``port``: the arm's
#: ``motion`` or ``state`` (empty for other links).
RAW_FRAME = "robocli_msgs/msg/RawFrame"
#: The same frames' schema in robocli's recordings (JSON, the data base64; see
#: :mod:`robocli.io.record.links`), which a ROS 2 bag or topic carries as :data:`RAW_FRAME`.
RAW_SCHEMA = "robocli.RawFrame"
RAW_FRAME_MSG = """\
builtin_interfaces/Time stamp
string link
string protocol
string direction
string port
uint8[] data
"""


class Ros2Unavailable(RobocliError):
    """The ``rosbags`` package is not installed."""


@functools.cache
def typestore() -> Any:
    """The type store (built once): ROS 2 Kilted's messages and :data:`RAW_FRAME`."""
    try:
        from rosbags.typesys import Stores, get_types_from_msg, get_typestore
    except ImportError:
        raise Ros2Unavailable("ROS 2 bags need the rosbags package: "
                              "pip install 'robocli-robots[record]'") from None  # fmt: skip
    store = get_typestore(Stores.ROS2_KILTED)
    store.register(get_types_from_msg(RAW_FRAME_MSG, RAW_FRAME))
    return store


def node_types() -> Any:
    """:func:`typestore`, once what a ROS 2 node on Zenoh needs besides is there too (xxhash:
    rmw_zenoh's GIDs); :class:`Ros2Unavailable` without it."""
    store = typestore()
    try:
        import xxhash  # noqa: F401
    except ImportError:
        raise Ros2Unavailable("--ros2 needs xxhash: pip install 'robocli-robots[ros2]'") from None
    return store


def message(msgtype: str, **fields: Any) -> Any:
    """A message object of ``msgtype`` (every field given)."""
    return typestore().types[msgtype](**fields)


def serialize(msg: Any, msgtype: str) -> bytes:
    """``msg`` as CDR (little-endian, encapsulation header included)."""
    return bytes(typestore().serialize_cdr(msg, msgtype))


def deserialize(data: bytes | memoryview, msgtype: str) -> Any:
    """A CDR message of ``msgtype`` as a message object. Raises
    :class:`~robocli.errors.RobocliError` for bytes that are not one (cut, an unknown type)."""
    store = typestore()
    if msgtype not in store.types:
        raise RobocliError(f"unknown ROS 2 message type {msgtype!r}")
    try:
        return store.deserialize_cdr(data, msgtype)
    except Exception as exc:
        raise RobocliError(f"a {msgtype} message does not decode ({exc})") from None


@functools.cache
def msgdef(msgtype: str) -> str:
    """The ``ros2msg`` schema text of ``msgtype``, its dependencies included."""
    text: str = typestore().generate_msgdef(msgtype, ros_version=2)[0]
    return text


@functools.cache
def type_hash(msgtype: str) -> str:
    """``RIHS01_<sha256 hex>`` of ``msgtype``."""
    digest: str = typestore().hash_rihs01(msgtype)
    return digest


def plain(msg: Any) -> Any:
    """A message object as plain Python: dicts of fields, lists for arrays (numpy arrays
    too), numbers and strings; ``uint8[]`` stays ``bytes``."""
    fields = getattr(msg, "__dataclass_fields__", None)
    if fields is not None:
        # a ROS 2 field name starts with a lower-case letter; constants are upper case
        return {name: plain(getattr(msg, name)) for name in fields if name[:1].islower()}
    if isinstance(msg, list | tuple):
        return [plain(v) for v in msg]
    tolist = getattr(msg, "tolist", None)
    if tolist is not None:
        if getattr(getattr(msg, "dtype", None), "char", "") == "B":
            return bytes(msg)
        return tolist()
    return msg
