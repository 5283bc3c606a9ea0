"""A live ROS 2 sink takes the decoders' samples as dicts (``write_sample``): no JSON made
and parsed again, an image's bytes never base64. What it maps them to is the same ROS 2
messages as the JSON a recording gets, and a SIP's odometry comes first."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("rosbags")

from robocli.ros2 import Mapper, Ros2Message


class _Sink:
    """The part of :class:`~robocli.io.record.links.Sink` a decoder writes with, mapping
    each sample to ROS 2 as :class:`~robocli.ros2.live.Ros2Topics` does (``direct``: it
    also has ``write_sample``)."""

    def __init__(self) -> None:
        self.links: dict[str, Any] = {}
        self.channels: list[tuple[str, str]] = []
        self.out: list[Ros2Message] = []
        self.mapper = Mapper()

    def channel(self, topic: str, schema: str | None, **_: Any) -> int:
        self.channels.append((topic, schema or ""))
        return len(self.channels)

    def write(self, cid: int, data: bytes, log_ns: int, publish_ns: int | None = None) -> None:
        self._map(cid, json.loads(data))

    def _map(self, cid: int, sample: dict[str, Any]) -> None:
        topic, schema = self.channels[cid - 1]
        self.out.extend(self.mapper.map(schema, topic, sample))


class _DirectSink(_Sink):
    direct = 0  #: samples given as dicts

    def write_sample(self, cid: int, sample: dict[str, Any], log_ns: int,
                     publish_ns: int | None = None) -> None:  # fmt: skip
        for v in sample.values():  # never base64 text for bytes
            assert not (isinstance(v, str) and len(v) > 64)
        self.direct += 1
        self._map(cid, sample)


def _sips(feed: Callable[[str, bytes, int], None]) -> int:
    from robocli.io.capture import read_capture

    trace = Path(__file__).resolve().parents[1] / "data/arcos/b_simpleMotionCommands.jsonl"
    n = 0
    for i, f in enumerate(read_capture(trace)):
        if f.direction == "rx" and f.frame[3] & 0xF0 == 0x30:
            feed("rx", f.frame[3:-2], 1_795_000_000_000_000_000 + i * 100_000_000)
            n += 1
    return n


def test_pioneer_sips_map_alike_and_odometry_first() -> None:
    from robocli.io.record.pioneer import PioneerDecoder
    from robocli.robots.pioneer import ROBOT_PARAMS

    sinks = (_Sink(), _DirectSink())
    for sink in sinks:
        n = _sips(PioneerDecoder(sink, "pioneer", ROBOT_PARAMS["p3dx"]))  # type: ignore[arg-type]
    text, direct = (s.out for s in sinks)
    assert n > 100 and len(direct) == len(text) == 5 * n  # tf, sonar, odom, battery, diagnostics
    assert sorted(direct) == sorted(text)
    assert [m.topic for m in direct[:5]][0] == "/pioneer/odom"  # first: what a node waits for
    assert [m.topic for m in text[:5]][0] == "/tf"  # (a recording keeps its order)


class _Clock:
    offset = 0.0

    def __init__(self) -> None:
        self.sync = self


def _image_frame(mtype: Any, w: int, h: int, blobs: list[bytes], compression: int = 0) -> bytes:
    from robocli.devices.hub.decode import HEADER
    from robocli.protocols.ros4mat import record_dtype

    infos = np.zeros(len(blobs), dtype=record_dtype(mtype))
    for info, blob in zip(infos, blobs, strict=True):
        info["width"], info["height"], info["size_data"] = w, h, len(blob)
        info["compression"], info["t"] = compression, 1_795_000_000.25
    body = infos.tobytes() + b"".join(blobs)
    return HEADER.pack(mtype, 0, 0, len(blobs), len(body), len(body), 0, 0.0) + body


@pytest.mark.parametrize("compression", [0, 1])
def test_hub_images_map_alike_from_bytes(compression: int) -> None:
    from robocli.io.record.hub import HubDecoder
    from robocli.protocols.ros4mat import MsgType

    blobs = [bytes(range(i, i + 12)) for i in range(3)]
    sinks = (_Sink(), _DirectSink())
    for sink in sinks:
        decoder = HubDecoder(sink, "hub1", _Clock())  # type: ignore[arg-type]
        decoder("rx", _image_frame(MsgType.WEBCAM, 2, 2, blobs, compression), 0)
    text, direct = (s.out for s in sinks)
    assert len(direct) == 3 and direct == text
    assert sinks[1].direct == 3
    kind = "sensor_msgs/msg/CompressedImage" if compression else "sensor_msgs/msg/Image"
    assert {m.msgtype for m in direct} == {kind}
    assert all(m.data.endswith(blob) for m, blob in zip(direct, blobs, strict=True))
