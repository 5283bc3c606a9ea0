"""The payload of one put of a hub sensor on Zenoh: a batch of samples (documented in the
README's Zenoh section, for programs that are not robocli).

A batch is a 32-byte little-endian header then the body of a ros4mat v3 data reply for the
same samples, record for record (``docs/protocols/ros4mat.md``: ADC records of 8 float32
volts then a float64 acquisition time, 40 bytes; IMU 9 float32 (accel g, gyro deg/s, mag
uT) then the time, 44 bytes; images: the info records, then each frame's bytes)::

    offset size  field
    0      4     magic b"RCZB"
    4      1     version (1)
    5      1     sensor: the ros4mat message id (0x04 ADC, 0x07 IMU, 0x10 camera ...)
    6      2     header size in bytes (32; a reader skips what it does not know)
    8      8     first: the sequence number of the batch's first sample (uint64)
    16     4     count: samples in the batch (uint32)
    20     4     body size in bytes (uint32)
    24     8     stamp: the hub's clock when the batch was put (float64, Unix seconds)

Sequence numbers count every sample the hub acquired for the sensor since it started
publishing it: a batch whose ``first`` is beyond the previous batch's ``first + count``
follows a gap of that many samples. The put's Zenoh encoding is
``application/octet-stream;robocli.batch.v1;sensor=<name>``.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from typing import Any

from robocli.errors import ProtocolError
from robocli.protocols.ros4mat import MsgType, record_dtype

__all__ = ["BATCH_HEADER", "BLOBS", "MAGIC", "SCHEMA", "VERSION", "Batch", "decode_batch",
           "encode_head", "head_size"]  # fmt: skip

MAGIC = b"RCZB"
VERSION = 1
SCHEMA = "robocli.batch.v1"
"""The schema part of the put's encoding (``application/octet-stream;robocli.batch.v1;...``)."""
BATCH_HEADER = struct.Struct("<4sBBHQIId")
MAX_BODY = 256 << 20  #: the largest body a batch may announce (bytes)
BLOBS = frozenset({MsgType.WEBCAM, MsgType.WEBCAM_STEREO, MsgType.HOKUYO, MsgType.KINECT})
"""Sensors whose records are info records followed by each frame's bytes."""


def head_size(kind: MsgType) -> int:
    """The bytes of one sample's record (for a sensor of :data:`BLOBS`, of its info
    records: two for a stereo pair)."""
    return record_dtype(kind).itemsize * (2 if kind == MsgType.WEBCAM_STEREO else 1)


@dataclass(frozen=True)
class Batch:
    """A decoded batch header and a view of its body (no copy)."""

    sensor_id: int
    first: int
    count: int
    stamp: float
    body: memoryview

    @property
    def end(self) -> int:
        """The sequence number after this batch's last sample."""
        return self.first + self.count


def encode_head(sensor_id: int, first: int, count: int, body_size: int, stamp: float) -> bytes:
    """The 32-byte header of a batch."""
    return BATCH_HEADER.pack(
        MAGIC, VERSION, sensor_id & 0xFF, BATCH_HEADER.size, first, count, body_size, stamp
    )


def decode_batch(payload: Any) -> Batch:
    """A batch's header and body; :class:`ProtocolError` for bytes that are not one: a
    sensor robocli does not know, a body that is not ``count`` records (for images and
    scans: shorter than ``count`` info records), a stamp that is not a finite time."""
    view = memoryview(payload).cast("B")
    if len(view) < BATCH_HEADER.size:
        raise ProtocolError(f"zenoh batch of {len(view)} bytes, shorter than its header")
    magic, version, sensor, head, first, count, size, stamp = BATCH_HEADER.unpack_from(view)
    if magic != MAGIC or version != VERSION:
        raise ProtocolError(f"not a robocli batch v{VERSION} (magic {bytes(magic)!r} v{version})")
    if head < BATCH_HEADER.size or size > MAX_BODY or head + size != len(view):
        raise ProtocolError(
            f"zenoh batch: header of {head} and body of {size} bytes in {len(view)} bytes"
        )
    try:
        kind = MsgType(sensor)
        per_sample = head_size(kind)
    except (ValueError, ProtocolError):
        raise ProtocolError(f"zenoh batch of an unknown sensor 0x{sensor:02x}") from None
    records = count * per_sample
    if records > size or (kind not in BLOBS and records != size):
        raise ProtocolError(
            f"zenoh batch: {count} samples of {per_sample} bytes in a body of {size} bytes"
        )
    if not math.isfinite(stamp) or stamp < 0:
        raise ProtocolError(f"zenoh batch: a stamp of {stamp!r} s")
    return Batch(sensor, first, count, stamp, view[head:])
