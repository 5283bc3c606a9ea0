"""The ROS 2 side of an MCAP file: what makes it a bag that ``ros2 bag play`` takes.

The rules are those of MCAP's ``ros2`` profile and of rosbag2's MCAP storage (which writes
and reads them):

- the header's profile is ``ros2``;
- a schema per type, named ``pkg/msg/Type``, encoding ``ros2msg``, holding the type's
  ``.msg`` text and its dependencies' (:func:`~robocli.ros2.types.msgdef`);
- a channel per topic, message encoding ``cdr`` on every one (rosbag2 refuses a bag whose
  topics mix serialisation formats), with the metadata ``offered_qos_profiles`` (the QoS a
  player offers: YAML as rosbag2 writes it, format 9) and ``topic_type_hash`` (RIHS01);
  robocli's raw channels keep their own metadata too (``protocol``, ``link``, ``direction``,
  ``port``: what ``dump --file`` looks for);
- at the end, the metadata record ``rosbag2`` with ``serialized_metadata`` (the bag's
  ``metadata.yaml`` document: topics, counts, times) and ``ROS_DISTRO``. A bag cut short
  has none; rosbag2 reads the file without it (the record is optional), from the MCAP
  summary or a scan.

:class:`BagChannels` does this over an ``mcap`` writer for :class:`~robocli.io.record.Recorder`
(``ros2=True``) and :func:`~robocli.io.convert.convert`.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

from robocli.ros2 import types as T
from robocli.ros2.mapping import Mapper, Ros2Message

__all__ = ["PROFILE", "ROS_DISTRO", "BagChannels", "is_ros2", "metadata_yaml", "qos_profiles"]

PROFILE = "ros2"
#: The distribution whose message definitions the bag's schemas hold.
ROS_DISTRO = "kilted"
#: Topics a late subscriber must still get (a latched publisher): transient local.
_LATCHED = ("/tf_static", "/robot_description")
_INFINITE = {"sec": 9223372036, "nsec": 854775807}  # RMW_DURATION_INFINITE, as rosbag2 writes it


def qos_profiles(topic: str) -> str:
    """``offered_qos_profiles`` of ``topic``: reliable (a reliable offer matches both
    reliable and best-effort subscribers), keep last 10 (100 for ``/tf``), volatile, but
    transient local and depth 1 for latched topics (``/tf_static``, every
    ``robot_description``)."""
    latched = topic in _LATCHED or topic.endswith("/robot_description")
    profile = {
        "history": "keep_last", "depth": 1 if latched else 100 if topic == "/tf" else 10,
        "reliability": "reliable",
        "durability": "transient_local" if latched else "volatile",
        "deadline": dict(_INFINITE), "lifespan": dict(_INFINITE), "liveliness": "automatic",
        "liveliness_lease_duration": dict(_INFINITE), "avoid_ros_namespace_conventions": False,
    }  # fmt: skip
    return _yaml([profile])


def is_ros2(profile: str, schema_encoding: str, message_encoding: str) -> bool:
    """Whether a channel (of a file with ``profile``) holds ROS 2 CDR."""
    return message_encoding == "cdr" and (schema_encoding == "ros2msg" or profile == PROFILE)


class BagChannels:
    """ROS 2 schemas, channels and counts over an ``mcap`` writer (``register_schema``,
    ``register_channel``, ``add_metadata``): start the writer with :data:`PROFILE`, take a
    channel id per ROS 2 topic from :meth:`channel`, and call :meth:`finish` before the
    writer's own ``finish``. ``prefix_frames``: see :class:`~robocli.ros2.mapping.Mapper`."""

    def __init__(self, writer: Any, *, prefix_frames: bool = False) -> None:
        self.writer = writer
        self.mapper = Mapper(prefix_frames=prefix_frames)
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, tuple[int, str]] = {}
        self.counts: dict[str, int] = {}
        self.first_ns: int | None = None
        self.last_ns = 0

    def channel(self, topic: str, msgtype: str, metadata: dict[str, str] | None = None) -> int:
        """The channel id of ``topic`` (registered on first use with its schema). A topic
        keeps its first type: a second type on it raises
        :class:`~robocli.errors.RobocliError` (a bag topic has one type)."""
        known = self._channels.get(topic)
        if known is not None:
            if known[1] != msgtype:
                from robocli.errors import RobocliError

                raise RobocliError(f"{topic} is {known[1]} in this bag, not {msgtype}")
            return known[0]
        sid = self._schemas.get(msgtype)
        if sid is None:
            sid = self._schemas[msgtype] = self.writer.register_schema(
                msgtype, "ros2msg", T.msgdef(msgtype).encode())  # fmt: skip
        meta = {"offered_qos_profiles": qos_profiles(topic),
                "topic_type_hash": T.type_hash(msgtype), **(metadata or {})}  # fmt: skip
        cid: int = self.writer.register_channel(topic, "cdr", sid, meta)
        self._channels[topic] = (cid, msgtype)
        self.counts[topic] = 0
        return cid

    def map(self, kind: str, topic: str, sample: dict[str, Any],
            metadata: dict[str, str] | None = None) -> list[tuple[int, Ros2Message]]:  # fmt: skip
        """``sample`` (robocli schema ``kind`` on robocli ``topic``) as ROS 2 messages with
        their channel ids; ``metadata`` goes to a channel whose topic stays ``topic`` (the
        raw channels'). Counts them (see :meth:`finish`)."""
        out = []
        for m in self.mapper.map(kind, topic, sample):
            cid = self.channel(m.topic, m.msgtype, metadata if m.topic == topic else None)
            out.append((cid, m))
        return out

    def count(self, topic: str, log_ns: int) -> None:
        """One message on ``topic`` at ``log_ns`` is in the bag (for the metadata)."""
        self.counts[topic] += 1
        if self.first_ns is None or log_ns < self.first_ns:
            self.first_ns = log_ns
        self.last_ns = max(self.last_ns, log_ns)

    def finish(self, file_name: str) -> None:
        """Write the ``rosbag2`` metadata record (the bag's ``metadata.yaml`` document)."""
        self.writer.add_metadata("rosbag2", {
            "serialized_metadata": _yaml(self.document(file_name)), "ROS_DISTRO": ROS_DISTRO,
        })  # fmt: skip

    def document(self, file_name: str) -> dict[str, Any]:
        """The ``rosbag2_bagfile_information`` of the bag (version 9, storage ``mcap``)."""
        start = self.first_ns or 0
        duration = max(0, self.last_ns - start)
        total = sum(self.counts.values())
        topics = [{
            "topic_metadata": {
                "name": topic, "type": msgtype, "serialization_format": "cdr",
                "offered_qos_profiles": _load(qos_profiles(topic)),
                "type_description_hash": T.type_hash(msgtype),
            },
            "message_count": self.counts[topic],
        } for topic, (_, msgtype) in self._channels.items()]  # fmt: skip
        return {
            "version": 9, "storage_identifier": "mcap", "duration": {"nanoseconds": duration},
            "starting_time": {"nanoseconds_since_epoch": start}, "message_count": total,
            "topics_with_message_count": topics, "compression_format": "",
            "compression_mode": "", "relative_file_paths": [file_name],
            "files": [{"path": file_name, "starting_time": {"nanoseconds_since_epoch": start},
                       "duration": {"nanoseconds": duration}, "message_count": total}],
            "custom_data": {"generator": "robocli"}, "ros_distro": ROS_DISTRO,
        }  # fmt: skip


def metadata_yaml(document: dict[str, Any]) -> str:
    """A bag folder's ``metadata.yaml`` text of :meth:`BagChannels.document`."""
    return _yaml({"rosbag2_bagfile_information": document}) + "\n"


def _yaml(value: Any) -> str:
    from ruamel.yaml import YAML  # rosbags' own dependency

    yaml = YAML(typ="safe")
    yaml.default_flow_style = False
    out = io.StringIO()
    yaml.dump(value, out)
    return out.getvalue().strip()


def _load(text: str) -> Any:
    from ruamel.yaml import YAML

    return YAML(typ="safe").load(text)


def bag_folder(path: Path) -> tuple[Path, Path]:
    """(the folder, its ``.mcap`` file) of a bag folder at ``path``: ``path/NAME_0.mcap``,
    as ``ros2 bag record`` names it."""
    return path, path / f"{path.name}_0.mcap"


class Translator:
    """robocli's channels turned into a ROS 2 bag's as they are written: what the recorder's
    decoders register (:meth:`channel`: a robocli topic and schema) gets an id of its own, and
    each JSON message written on it (:meth:`write`) goes into the bag as the ROS 2 messages
    it maps to (:mod:`robocli.ros2.mapping`), at the same log time, published at the
    message's own stamp (the publish time given when the stamp is missing)."""

    def __init__(self, bag: BagChannels) -> None:
        self.bag = bag
        self._virtual: list[tuple[str, str, dict[str, str] | None]] = []
        self._sequence: dict[int, int] = {}

    def channel(self, topic: str, schema: str | None, metadata: dict[str, str] | None) -> int:
        """An id for robocli's ``topic`` of ``schema`` (ids start at 1)."""
        self._virtual.append((topic, schema or "", metadata))
        return len(self._virtual)

    def write(self, vid: int, data: bytes, log_ns: int, publish_ns: int | None,
              add: Any) -> int:  # fmt: skip
        """Map the JSON message ``data`` of channel ``vid`` and hand each ROS 2 message to
        ``add(cid, log_ns, data, publish_ns, sequence)``; returns how many. Raises
        ``ValueError`` (not JSON) or :class:`~robocli.errors.RobocliError` (does not map)."""
        import json

        topic, schema, metadata = self._virtual[vid - 1]
        bag = self.bag
        mapped = bag.map(schema, topic, json.loads(data), metadata)
        for cid, m in mapped:
            seq = self._sequence.get(cid, 0)
            self._sequence[cid] = seq + 1
            publish = m.t_ns or (log_ns if publish_ns is None else publish_ns)
            add(cid, log_ns, m.data, publish, seq)
            bag.count(m.topic, log_ns)
        return len(mapped)
