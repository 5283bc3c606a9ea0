"""A ROS 2 node on a Zenoh session, as ``rmw_zenoh_cpp`` shows one (the mapping:
:mod:`robocli.ros2.rmw`), with no ROS installed: ``ros2 node list`` and ``ros2 topic list``
on a machine running rmw_zenoh see it through its liveliness tokens, and its publishers'
samples carry the attachment rmw_zenoh requires.

* :class:`Ros2Node` declares the node's ``NN`` token; entity ids come from one counter per
  node, starting at the node's own id (rmw_zenoh counts per context).
* :meth:`Ros2Node.publisher` declares an ``MP`` token and a Zenoh publisher on the topic's
  key: a transient-local one keeps its last ``depth`` samples for late joiners (a zenoh-ext
  advanced publisher with a cache and publisher detection, as rmw_zenoh declares it).
* :meth:`Ros2Node.subscriber` declares an ``MS`` token and a subscriber that hands each
  sample's CDR bytes to a callback; samples without rmw_zenoh's attachment, not CDR, or over
  the size limit are dropped and counted, and a callback that raises is logged, never
  raised into Zenoh's thread.

Type hashes (RIHS01) come from robocli's ROS 2 type store (:func:`robocli.ros2.types.type_hash`).
"""

from __future__ import annotations

import itertools
import logging
import re
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from robocli.errors import ProtocolError
from robocli.ros2.rmw import (
    BEST_EFFORT,
    DEFAULT_QOS,
    KEEP_ALL,
    RELIABLE,
    Attachment,
    Qos,
    check_cdr,
    entity_token,
    gid,
    node_token,
    qualified,
    topic_key,
)
from robocli.ros2.types import type_hash
from robocli.zenoh.session import import_zenoh, undeclare

if TYPE_CHECKING:
    import zenoh

__all__ = ["MAX_MESSAGE", "Ros2Node", "Ros2Publisher", "Ros2Subscriber", "node_name"]

log = logging.getLogger("robocli.ros2")

MAX_MESSAGE = 1 << 20
"""The largest ROS 2 message a subscriber decodes (bytes): a command, a trajectory."""


def node_name(name: str) -> str:
    """A robocli name as a ROS 2 node name (letters, digits, ``_``; not a digit first)."""
    out = re.sub(r"[^A-Za-z0-9_]", "_", name)
    return out if out[:1].isalpha() or out[:1] == "_" else f"n_{out}"


class Ros2Publisher:
    """One ROS 2 publisher: :meth:`publish` puts a CDR message with its attachment."""

    def __init__(self, node: Ros2Node, topic: str, ros_type: str, qos: Qos) -> None:
        z = import_zenoh()
        self.topic, self.ros_type, self.qos = topic, ros_type, qos
        h = type_hash(ros_type)
        self.key = topic_key(node.domain, topic, ros_type, h)
        self.token_key = node.entity_token("MP", topic, ros_type, h, qos)
        self.gid = gid(self.token_key)
        self._seq = 1  # rmw_zenoh numbers each publisher's samples from 1
        self._lock = threading.Lock()
        self.published = 0
        options: dict[str, Any] = {
            "reliability": (z.Reliability.RELIABLE if qos.reliability == RELIABLE
                            else z.Reliability.BEST_EFFORT),
            "congestion_control": (z.CongestionControl.BLOCK if qos.reliability == RELIABLE
                                   and qos.history == KEEP_ALL else z.CongestionControl.DROP),
        }  # fmt: skip
        if qos.transient_local:
            self._pub: Any = z.ext.declare_advanced_publisher(
                node.session, self.key, cache=z.ext.CacheConfig(max(1, qos.depth)),
                publisher_detection=True,
                sample_miss_detection=(z.ext.MissDetectionConfig(sporadic_heartbeat=0.5)
                                       if qos.reliability != BEST_EFFORT else None),
                **options,
            )  # fmt: skip
        else:
            self._pub = node.session.declare_publisher(self.key, **options)
        self._token = node.session.liveliness().declare_token(self.token_key)

    @property
    def matching(self) -> bool:
        """Whether a subscriber matches the topic now (a transient-local publisher: always
        True, its cache serves the ones to come)."""
        status = getattr(self._pub, "matching_status", None)
        return True if status is None else bool(status.matching)

    def publish(self, cdr: bytes, t_ns: int | None = None) -> None:
        """Put one CDR-encoded message (``t_ns``: its source time, ns since the epoch; now
        when None). A session that is closing refuses it: logged, not raised."""
        with self._lock:
            seq = self._seq
            self._seq += 1
        stamp = time.time_ns() if t_ns is None else t_ns
        try:
            self._pub.put(cdr, attachment=Attachment(seq, stamp, self.gid).encode())
        except import_zenoh().ZError:
            log.debug("%s: put failed", self.topic, exc_info=True)
            return
        self.published += 1

    def close(self) -> None:
        for entity in (self._token, self._pub):
            undeclare(entity)


class Ros2Subscriber:
    """One ROS 2 subscription: ``callback(cdr, attachment)`` per valid sample."""

    def __init__(self, node: Ros2Node, topic: str, ros_type: str, qos: Qos,
                 callback: Callable[[bytes, Attachment], None],
                 max_bytes: int = MAX_MESSAGE) -> None:  # fmt: skip
        self.topic, self.ros_type = topic, ros_type
        self._callback, self._max = callback, max_bytes
        h = type_hash(ros_type)
        self.key = topic_key(node.domain, topic, ros_type, h)
        self.dropped = 0  #: samples refused (no attachment, not CDR, too big)
        self.failed = 0  #: samples whose callback raised
        self._sub = node.session.declare_subscriber(self.key, self._on_sample)
        self._token = node.session.liveliness().declare_token(
            node.entity_token("MS", topic, ros_type, h, qos)
        )

    def _on_sample(self, sample: zenoh.Sample) -> None:
        try:
            raw = sample.attachment
            attachment = Attachment.decode(raw.to_bytes() if raw is not None else None)
            payload = check_cdr(sample.payload.to_bytes(), self._max)
        except ProtocolError as exc:
            self.dropped += 1
            if self.dropped == 1:
                log.warning("%s: %s (later ones only counted)", self.topic, exc)
            return
        try:
            self._callback(payload, attachment)
        except Exception:
            self.failed += 1
            log.error("%s: a message could not be handled", self.topic, exc_info=True)

    def close(self) -> None:
        for entity in (self._token, self._sub):
            undeclare(entity)


class Ros2Node:
    """A ROS 2 node named ``name`` in ``namespace`` on ROS domain ``domain``, declared on
    ``session`` (the caller's: :meth:`close` undeclares what the node declared)."""

    def __init__(self, session: zenoh.Session, name: str, *, namespace: str = "",
                 domain: int = 0) -> None:  # fmt: skip
        self.session = session
        self.name, self.domain = name, domain
        self.namespace = qualified(namespace or "/", name).rsplit("/", 1)[0]  # checks both
        self.zid = str(session.info.zid())
        self._ids = itertools.count()
        self.nid = next(self._ids)
        self.token_key = node_token(domain, self.zid, self.nid, self.namespace, name)
        self._entities: list[Ros2Publisher | Ros2Subscriber] = []
        self._token = session.liveliness().declare_token(self.token_key)

    def entity_token(self, kind: str, topic: str, ros_type: str, type_hash: str,
                     qos: Qos) -> str:  # fmt: skip
        """The token of a new entity of this node (takes the next entity id)."""
        return entity_token(self.domain, self.zid, self.nid, next(self._ids), kind,
                            self.namespace, self.name, topic, ros_type, type_hash, qos)  # fmt: skip

    def resolve(self, topic: str) -> str:
        """``topic`` fully qualified in the node's namespace."""
        return qualified(self.namespace, topic)

    def publisher(self, topic: str, ros_type: str, qos: Qos = DEFAULT_QOS) -> Ros2Publisher:
        """A publisher of ``ros_type`` on ``topic`` (relative: in the node's namespace)."""
        pub = Ros2Publisher(self, self.resolve(topic), ros_type, qos)
        self._entities.append(pub)
        return pub

    def subscriber(self, topic: str, ros_type: str,
                   callback: Callable[[bytes, Attachment], None], qos: Qos = DEFAULT_QOS,
                   max_bytes: int = MAX_MESSAGE) -> Ros2Subscriber:  # fmt: skip
        """A subscription to ``topic``; ``callback(cdr, attachment)`` on Zenoh's thread."""
        sub = Ros2Subscriber(self, self.resolve(topic), ros_type, qos, callback, max_bytes)
        self._entities.append(sub)
        return sub

    def close(self) -> None:
        """Undeclare every entity, then the node. Idempotent."""
        while self._entities:
            self._entities.pop().close()
        undeclare(self._token)
