"""The direct CDR encoders of robocli.ros2.cdr write the same bytes as rosbags' serializer
of the same message, for every alignment a frame id, an encoding or a format can leave, and
the mapping gives the same message whether an image's bytes come as base64 (a recording's
JSON) or as the bytes themselves (a live sink's dicts)."""

from __future__ import annotations

import base64

import numpy as np
import pytest

pytest.importorskip("rosbags")

from robocli.io import schemas as S
from robocli.ros2 import Mapper, serialize
from robocli.ros2.cdr import compressed_image_cdr, image_cdr
from robocli.ros2.types import message

NS = 1_764_000_000_123_456_789
FRAMES = ["", "c", "ab", "abc", "abcd", "hub1/depth"]


def _header(ns: int, frame: str) -> object:
    sec, nsec = divmod(ns, 1_000_000_000)
    stamp = message("builtin_interfaces/msg/Time", sec=sec, nanosec=nsec)
    return message("std_msgs/msg/Header", stamp=stamp, frame_id=frame)


@pytest.mark.parametrize("frame", FRAMES)
@pytest.mark.parametrize("encoding", ["rgb8", "16UC1", "mono8", "bgra8"])
@pytest.mark.parametrize("size", [0, 1, 5, 12])
def test_image_bytes_equal_rosbags_serializer(frame: str, encoding: str, size: int) -> None:
    pixels = np.random.default_rng(size).integers(0, 256, size, dtype=np.uint8)
    want = serialize(message("sensor_msgs/msg/Image", header=_header(NS, frame), height=1,
                             width=size, encoding=encoding, is_bigendian=0, step=size,
                             data=pixels), "sensor_msgs/msg/Image")  # fmt: skip
    got = image_cdr(NS, frame, 1, size, encoding, size, memoryview(pixels.tobytes()))
    assert got == want


@pytest.mark.parametrize("frame", FRAMES)
@pytest.mark.parametrize("fmt", ["", "png", "jpeg", "jpeg2"])
@pytest.mark.parametrize("ns", [NS, 0, -1_500_000_000])
def test_compressed_image_bytes_equal_rosbags_serializer(frame: str, fmt: str, ns: int) -> None:
    data = b"\xff\xd8 some jpeg \xff\xd9"
    want = serialize(message("sensor_msgs/msg/CompressedImage", header=_header(ns, frame),
                             format=fmt, data=np.frombuffer(data, np.uint8)),
                     "sensor_msgs/msg/CompressedImage")  # fmt: skip
    assert compressed_image_cdr(ns, frame, fmt, data) == want


def test_images_map_alike_from_base64_and_from_bytes() -> None:
    pixels = bytes(range(24))
    mapper = Mapper()
    for raw in (False, True):
        rgb = S.raw_image(NS, "hub/camera", 4, 2, "rgb8", 12, memoryview(pixels), raw=raw)
        jpeg = S.compressed_image(NS, "hub/camera", pixels, raw=raw)
        assert (rgb["data"] == pixels) is raw and (jpeg["data"] == pixels) is raw
        if not raw:
            assert base64.b64decode(rgb["data"]) == pixels
        (image,) = mapper.map("foxglove.RawImage", "/hub/camera", rgb)
        (comp,) = mapper.map("foxglove.CompressedImage", "/hub/camera", jpeg)
        assert image.data == image_cdr(NS, "camera", 2, 4, "rgb8", 12, pixels)
        assert comp.data == compressed_image_cdr(NS, "camera", "jpeg", pixels)
