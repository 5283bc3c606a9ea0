"""Direct CDR encoders of the ROS 2 messages whose bulk is one array (a laser's ranges, an
image's pixels): the bytes written straight from the arrays, without a message object, for
the live topics' hot path (:mod:`robocli.ros2.mapping` uses them). Each one's bytes equal
what ``rosbags``' serializer makes of the same message (tests/ros2/test_cdr.py)."""

from __future__ import annotations

import math
import struct
from typing import Any

import numpy as np

__all__ = ["compressed_image_cdr", "image_cdr", "laser_scan_cdr", "sample_bytes"]

_F4 = np.float32
_RANGE_MIN, _RANGE_MAX = 0.01, 30.0
#: stamp, frame_id length; then 7 floats and the ranges' length (all 4-aligned after the
#: padded string); a uint32
_HEAD, _SCAN, _U32 = struct.Struct("<iII"), struct.Struct("<7fI"), struct.Struct("<I")
_CDR_LE = b"\x00\x01\x00\x00"  #: the encapsulation header: CDR, little-endian


def laser_scan_cdr(ns: int, frame_id: str, angle_min: float, angle_max: float,
                   ranges: np.ndarray, intensities: np.ndarray | None = None) -> bytes:  # fmt: skip
    """A sensor_msgs/LaserScan as CDR, straight from float32 arrays (a 1081-beam scan in a
    few microseconds): robocli's 0 (no return) becomes +inf, ``frame_id`` is written as
    given. The bytes equal :func:`.types.serialize` of the same message."""
    r = np.asarray(ranges, _F4)
    n = len(r)
    top = float(r.max()) if n else 0.0
    if not math.isfinite(top):  # an infinity or a NaN given: the farthest finite range
        top = float(r[np.isfinite(r)].max(initial=0.0))
    rmax = max(_RANGE_MAX, top)
    if n and not r.all():
        r = np.where(r == 0, np.float32(np.inf), r)
    inten = np.asarray(() if intensities is None else intensities, _F4)
    inc = (angle_max - angle_min) / (n - 1) if n > 1 else 0.0
    sec, nsec = divmod(ns, 1_000_000_000)
    fid = frame_id.encode() + b"\0"
    head = _HEAD.pack(sec, nsec, len(fid))  # after the encapsulation: CDR offsets from here
    pad = -(len(head) + len(fid)) % 4
    body = _SCAN.pack(angle_min, angle_max, inc, 0.0, 0.0, _RANGE_MIN, rmax, n)
    return b"".join((_CDR_LE, head, fid, b"\0" * pad, body, r.tobytes(), _U32.pack(len(inten)),
                     inten.tobytes()))  # fmt: skip


# ---------------------------------------------------------------------- images, fast


class _Cdr:
    """A little-endian CDR body being written: parts and their running length (alignment
    counts from after the encapsulation header, as CDR's does)."""

    __slots__ = ("n", "parts")

    def __init__(self) -> None:
        self.parts: list[bytes | memoryview] = [_CDR_LE]
        self.n = 0

    def add(self, data: bytes | memoryview) -> None:
        self.parts.append(data)
        self.n += len(data)

    def u32(self, value: int) -> None:
        pad = -self.n % 4
        if pad:
            self.add(b"\0" * pad)
        self.add(_U32.pack(value))

    def string(self, text: str) -> None:
        raw = text.encode() + b"\0"
        self.u32(len(raw))
        self.add(raw)

    def header(self, ns: int, frame_id: str) -> None:
        sec, nsec = divmod(ns, 1_000_000_000)
        self.u32(sec & 0xFFFFFFFF)  # int32 sec: its two's complement bytes
        self.add(_U32.pack(nsec))
        self.string(frame_id)

    def octets(self, data: bytes | memoryview) -> bytes:
        """The body ending with ``uint8[] data`` (the only copy of the bytes is the join)."""
        self.u32(len(data))
        self.parts.append(data)
        return b"".join(self.parts)


def image_cdr(ns: int, frame_id: str, height: int, width: int, encoding: str, step: int,
              data: bytes | memoryview) -> bytes:  # fmt: skip
    """A sensor_msgs/Image as CDR, straight from the pixels' bytes (no message object, one
    copy). ``frame_id`` and ``encoding`` are written as given, little-endian pixels. The
    bytes equal :func:`.types.serialize` of the same message."""
    out = _Cdr()
    out.header(ns, frame_id)
    out.u32(height)
    out.add(_U32.pack(width))
    out.string(encoding)
    out.add(b"\0")  # is_bigendian
    out.u32(step)
    return out.octets(data)


def compressed_image_cdr(ns: int, frame_id: str, fmt: str, data: bytes | memoryview) -> bytes:
    """A sensor_msgs/CompressedImage as CDR, straight from the encoded image's bytes (see
    :func:`image_cdr`)."""
    out = _Cdr()
    out.header(ns, frame_id)
    out.string(fmt)
    return out.octets(data)


def sample_bytes(data: Any) -> bytes | memoryview:
    """A sample's ``data``: base64 text (a recording's JSON) or the bytes themselves."""
    if isinstance(data, str):
        import base64

        return base64.b64decode(data)
    return memoryview(data).cast("B")
