"""robocli's live samples as ROS 2 topics on Zenoh (rmw_zenoh's mapping), with the same
decoders and the same ROS 2 mapping as a ROS 2 bag, so that a topic and a bag cannot differ.

:class:`Ros2Topics` is a recording sink (:class:`robocli.io.record.links.Sink`): a device's
decoders (``attach_pioneer``, ``attach_arm``, the hub's :class:`HubDecoder`) write robocli
messages into it as they would into a :class:`~robocli.io.record.Recorder`; each becomes the
ROS 2 messages :class:`~robocli.ros2.mapping.Mapper` maps it to (one per sample: a batch is
already split by the decoders), published by one :class:`~robocli.ros2.node.Ros2Node`.
Raw link bytes are not published (ROS 2 has no type for them).

**Names.** robocli's topic ``/NAME/KEY`` becomes ``KEY`` and a shared one (``/tf``,
``/diagnostics``) loses its leading ``/``: every topic is relative to the node's namespace
(``--ros2-namespace``), as ROS 2 drivers of several robots are run, ``tf`` and ``tf_static``
included. Frames are REP 105's plain names (``odom``, ``base_link``, ``laser``...).

**QoS**, as a bag offers it (:func:`robocli.ros2.bag.qos_profiles`): reliable, volatile, keep
last 10 (``tf``: 100); ``tf_static`` and ``robot_description`` transient local, depth 1, so
that RViz joining later still gets them.

Work queued with :meth:`put` (a decoder's, from a device's reader thread) runs on the sink's
own thread; what does not fit its bounded queue is dropped and counted, never waited for.
"""

from __future__ import annotations

import json
import logging
import math
import queue
import threading
import time
import xml.etree.ElementTree as ET
from collections.abc import Callable
from typing import Any

from robocli.errors import RobocliError
from robocli.ros2.mapping import Mapper, Ros2Message
from robocli.ros2.node import Ros2Node, Ros2Publisher
from robocli.ros2.rmw import DEFAULT_QOS, LATCHED_QOS, Qos
from robocli.ros2.types import RAW_SCHEMA
from robocli.sink import SinkBase

__all__ = ["Ros2Topics", "static_transforms"]

log = logging.getLogger("robocli.ros2")

_LATCHED = {"tf_static", "robot_description"}


def _qos(topic: str) -> Qos:
    if topic in _LATCHED:
        return LATCHED_QOS
    return Qos(depth=100) if topic == "tf" else DEFAULT_QOS


class Ros2Topics(SinkBase):
    """The sink (see the module) of robocli ``name``'s messages, published by ``node``.

    ``max_queue`` / ``max_queue_bytes``: the work items (and the bytes they carry) that may
    wait for the sink's thread; what would go past either is dropped (:attr:`dropped`)."""

    def __init__(self, node: Ros2Node, name: str, *, max_queue: int = 1024,
                 max_queue_bytes: int = 64 << 20) -> None:  # fmt: skip
        super().__init__()
        self.node, self.name = node, name
        self.links: dict[str, Any] = {}
        self.mapper = Mapper()
        self.published = 0  #: ROS 2 messages put
        self.dropped = 0  #: work items dropped (queue full)
        self.errors = 0  #: messages that did not map (logged once)
        #: when a set: every publisher a message went out on is added (see hub.frontends.ros2)
        self.used: set[Ros2Publisher] | None = None
        self._prefix = f"/{name}/"
        self._channels: list[tuple[str, str]] = []
        self._publishers: dict[tuple[str, str], Ros2Publisher] = {}
        self._queue: queue.Queue[tuple[Callable[..., None], tuple[Any, ...], int] | None] = (
            queue.Queue(max_queue))  # fmt: skip
        self._max_bytes, self._queued_bytes = max_queue_bytes, 0
        self._lock = threading.Lock()  # publishers are made by the sink thread and callers
        self._thread = threading.Thread(target=self._run, name=f"ros2-{name}", daemon=True)
        self._thread.start()

    # ------------------------------------------------------------------ the Sink protocol

    def put(self, handler: Callable[..., None], args: tuple[Any, ...], size: int = 64) -> bool:
        with self._lock:
            if self._queued_bytes + size > self._max_bytes:
                self.dropped += 1
                return False
            self._queued_bytes += size
        try:
            self._queue.put_nowait((handler, args, size))
        except queue.Full:
            with self._lock:
                self._queued_bytes -= size
            self.dropped += 1
            return False
        return True

    def channel(self, topic: str, schema: str | None, *, encoding: str = "json",
                metadata: dict[str, str] | None = None) -> int:  # fmt: skip
        self._channels.append((topic, "" if schema in (None, RAW_SCHEMA) else schema))
        return len(self._channels)

    def write(self, cid: int, data: bytes, log_ns: int, publish_ns: int | None = None) -> None:
        if self._channels[cid - 1][1]:  # (a raw channel: robocli's own, not ROS 2's)
            try:
                sample = json.loads(data)
            except ValueError as exc:
                self._error(self._channels[cid - 1][0], exc)
                return
            self.write_sample(cid, sample, log_ns, publish_ns)

    def write_sample(self, cid: int, sample: dict[str, Any], log_ns: int,
                     publish_ns: int | None = None) -> None:  # fmt: skip
        """:meth:`write` of the message as the decoder's dict, not its JSON (a decoder that
        sees this method gives its samples so: no JSON made and parsed again, an image's
        ``data`` its bytes, not base64)."""
        topic, schema = self._channels[cid - 1]
        if not schema:
            return
        try:
            messages = self.mapper.map(schema, topic, sample)
        except (RobocliError, ValueError) as exc:
            self._error(topic, exc)
            return
        for m in messages:
            self.publish(m)

    def _error(self, topic: str, exc: Exception) -> None:
        self.errors += 1
        if self.errors == 1:
            log.warning("%s: %s does not map to ROS 2: %s (later ones only counted)",
                        self.name, topic, exc)  # fmt: skip

    # ------------------------------------------------------------------ publishing

    def relative(self, topic: str) -> str:
        """robocli's ``/NAME/KEY`` -> ``KEY``; ``/tf`` -> ``tf`` (see the module)."""
        if topic.startswith(self._prefix):
            return topic[len(self._prefix) :]
        return topic.lstrip("/")

    def publisher(self, topic: str, msgtype: str) -> Ros2Publisher:
        """The publisher of relative ``topic`` and ``msgtype`` (declared on first use)."""
        key = (topic, msgtype)
        pub = self._publishers.get(key)
        if pub is None:
            with self._lock:
                pub = self._publishers.get(key)
                if pub is None:
                    pub = self.node.publisher(topic, msgtype, _qos(topic))
                    self._publishers[key] = pub
        return pub

    def publish(self, m: Ros2Message) -> None:
        """Put one mapped message on its topic (relative to the node's namespace)."""
        pub = self.publisher(self.relative(m.topic), m.msgtype)
        pub.publish(m.data, m.t_ns or None)
        self.published += 1
        if self.used is not None:
            self.used.add(pub)

    def publish_static(self, urdf: str, t_ns: int | None = None) -> None:
        """``tf_static``: the model's fixed joints (wheels at 0), transient local, as
        ``robot_state_publisher`` would say them. (``robot_description`` itself comes from
        the device's decoders, as in a recording: :mod:`robocli.io.record.models`.)"""
        from robocli.ros2 import types as T

        stamp = _time(time.time_ns() if t_ns is None else t_ns)
        tfs = [T.message("geometry_msgs/msg/TransformStamped",
                         header=T.message("std_msgs/msg/Header", stamp=stamp, frame_id=parent),
                         child_frame_id=child,
                         transform=T.message("geometry_msgs/msg/Transform",
                                             translation=_vec(xyz), rotation=_quat(q)))
               for parent, child, xyz, q in static_transforms(urdf)]  # fmt: skip
        self.publisher("tf_static", "tf2_msgs/msg/TFMessage").publish(
            T.serialize(T.message("tf2_msgs/msg/TFMessage", transforms=tfs),
                        "tf2_msgs/msg/TFMessage"))  # fmt: skip

    # ------------------------------------------------------------------ the sink's thread

    def _run(self) -> None:
        while True:
            item = self._queue.get()
            if item is None:
                return
            handler, args, size = item
            try:
                handler(*args)
            except Exception:
                self.errors += 1
                log.error("%s: a sample could not be published", self.name, exc_info=True)
            finally:
                with self._lock:
                    self._queued_bytes -= size

    def close(self) -> None:
        """Detach from the devices, finish the queued work (bounded), stop. Idempotent."""
        self._detach_all()
        if self._thread.is_alive():
            try:
                self._queue.put(None, timeout=1.0)
            except queue.Full:
                log.warning("%s: ROS 2 work still queued at close", self.name)
            self._thread.join(timeout=5.0)


def static_transforms(
    urdf: str,
) -> list[tuple[str, str, tuple[float, float, float], tuple[float, float, float, float]]]:
    """(parent, child, xyz, quaternion xyzw) of the URDF's fixed and continuous joints (a
    continuous one at 0: robocli measures no wheel angle); an arm's revolute joints are its
    ``tf``'s."""
    root = ET.fromstring(urdf)
    out: list[tuple[str, str, tuple[float, float, float], tuple[float, float, float, float]]]
    out = []
    for joint in root.iter("joint"):
        parent, child = joint.find("parent"), joint.find("child")
        if parent is None or child is None:
            continue
        if joint.get("type") not in ("fixed", "continuous"):
            continue
        origin = joint.find("origin")
        xyz = _floats(origin.get("xyz") if origin is not None else None)
        rpy = _floats(origin.get("rpy") if origin is not None else None)
        out.append((parent.get("link", ""), child.get("link", ""), xyz, _rpy_quat(*rpy)))
    return out


def _floats(text: str | None) -> tuple[float, float, float]:
    values = [float(v) for v in (text or "0 0 0").split()]
    return (values + [0.0, 0.0, 0.0])[0], (values + [0.0] * 3)[1], (values + [0.0] * 3)[2]


def _rpy_quat(r: float, p: float, y: float) -> tuple[float, float, float, float]:
    cr, sr = math.cos(r / 2), math.sin(r / 2)
    cp, sp = math.cos(p / 2), math.sin(p / 2)
    cy, sy = math.cos(y / 2), math.sin(y / 2)
    return (sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy)  # fmt: skip


def _time(ns: int) -> Any:
    from robocli.ros2 import types as T

    sec, nsec = divmod(ns, 1_000_000_000)
    return T.message("builtin_interfaces/msg/Time", sec=sec, nanosec=nsec)


def _vec(xyz: tuple[float, float, float]) -> Any:
    from robocli.ros2 import types as T

    return T.message("geometry_msgs/msg/Vector3", x=xyz[0], y=xyz[1], z=xyz[2])


def _quat(q: tuple[float, float, float, float]) -> Any:
    from robocli.ros2 import types as T

    return T.message("geometry_msgs/msg/Quaternion", x=q[0], y=q[1], z=q[2], w=q[3])
