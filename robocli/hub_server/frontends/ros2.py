"""A hub's sensors as ROS 2 topics on Zenoh (``serve --zenoh --ros2``), beside its robocli
keys: every batch the hub's Zenoh front-end puts is decoded as a recording of the hub would
decode it (:class:`~robocli.io.record.hub.HubDecoder`: one message per sample, the batch
split) and mapped as a ROS 2 bag maps it (:mod:`robocli.ros2.mapping`), then published by
one ROS 2 node named after the hub (:class:`~robocli.ros2.live.Ros2Topics`): ``adc``,
``imu``, ``imu/mag``, ``gps``, ``battery``, ``diagnostics``, ``laser``, camera images...

The decoding and the publishing run on the sink's own thread, so the front-end's ticker
only copies each batch once; a sample's stamp is its acquisition time on the hub's clock,
mapped onto the host's Unix clock.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from robocli.devices.hub.decode import HEADER
from robocli.io.record.hub import HubDecoder
from robocli.protocols.ros4mat.ids import Compression
from robocli.ros2.live import Ros2Topics
from robocli.ros2.node import Ros2Node, node_name

if TYPE_CHECKING:
    import zenoh

    from robocli.hub_server.registry import SensorRegistry

__all__ = ["HubTopics"]


class _HubClock:
    """What :class:`HubDecoder` asks of a hub client: the offset of the hub's clock from the
    host's Unix clock (``sync.offset``), here read from the server's own clock."""

    def __init__(self, hub: SensorRegistry) -> None:
        self._hub = hub
        self.sync = self

    @property
    def offset(self) -> float:
        return float(self._hub.clock()) - time.time()


class HubTopics:
    """The ROS 2 node of hub ``name`` (see the module); :meth:`batch` is the Zenoh
    front-end's ``on_batch`` hook."""

    def __init__(self, hub: SensorRegistry, session: zenoh.Session, name: str, *, domain: int = 0,
                 namespace: str = "") -> None:  # fmt: skip
        self.node = Ros2Node(session, node_name(name), namespace=namespace, domain=domain)
        self.topics = Ros2Topics(self.node, name)
        self._decoder = HubDecoder(self.topics, name, _HubClock(hub))  # type: ignore[arg-type]
        self._used: dict[int, set[Any]] = {}  # sensor id -> the ROS 2 publishers it feeds
        self.skipped = 0  #: batches not decoded: no subscriber of their topics

    def batch(self, sensor_id: int, n: int, parts: Sequence[Any]) -> None:
        """One batch of ``n`` samples of ros4mat sensor ``sensor_id`` (its reply body in
        ``parts``): copied, then decoded and published on the sink's thread. A sensor whose
        ROS 2 topics no subscriber matches is skipped (counted in :attr:`skipped`): its first
        batch declares them, and it is published again as soon as one is matched."""
        used = self._used.get(sensor_id)
        if used is not None and not any(pub.matching for pub in used):
            self.skipped += 1
            return
        body = b"".join(parts)
        head = HEADER.pack(sensor_id, 0, 0, n, len(body), len(body), Compression.NONE, 0.0)
        self.topics.put(self._decode, (sensor_id, head + body, time.time_ns()), len(body))

    def _decode(self, sensor_id: int, frame: bytes, ns: int) -> None:
        """The sink's thread: decode, map, publish; note the publishers it used."""
        topics = self.topics
        topics.used = used = self._used.get(sensor_id) or set()
        try:
            self._decoder("rx", frame, ns)
        finally:
            topics.used = None
        if used:
            self._used[sensor_id] = used

    def close(self) -> None:
        self.topics.close()
        self.node.close()
