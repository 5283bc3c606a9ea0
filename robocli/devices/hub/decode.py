"""Zero-copy decoding of ros4mat data replies into :class:`Reading` objects, and their
alignment on one time base.

Part of :mod:`robocli.devices.hub.client` (import from there). A data reply's body is viewed in
place with :func:`numpy.frombuffer` and structured dtypes: the matrices the original MATLAB
client returns (fields x samples) are transposed views over the received bytes, never built
sample by sample. Only GPS, COMPUTER and BATTERY (mixed integer and float fields, reordered
for GPS) are copied, once per reply, with vectorised assignments; JPEG frames are decoded
one frame at a time (Pillow, optional).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from robocli.core import align_linear, align_nearest
from robocli.errors import DeviceError, InvalidArgument, ProtocolError, TimeoutError
from robocli.protocols.ros4mat import (
    HEADER_SIZE,
    RECORDS,
    Compression,
    MsgType,
    inflate,
    record_dtype,
    sensor_type,
)

#: ``msgHeader`` for the hot path (27 B, little-endian, packed).
HEADER = struct.Struct("<bbIIIIbd")
#: The most bytes the JPEG frames of one reply may decode to (a 16 MiB reply of small JPEGs
#: declaring large images could otherwise take gigabytes): 256 MiB is 45 frames of
#: 1600 x 1200, the largest ros4mat resolution.
MAX_DECODED_BYTES = 256 << 20


def _view_dtype(n_floats: int, itemsize: int) -> np.dtype[Any]:
    """``n_floats`` float32 then a float64 ``t``: a record viewed as one float vector."""
    return np.dtype(
        {"names": ["v", "t"], "formats": [("<f4", (n_floats,)), "<f8"],
         "offsets": [0, 4 * n_floats], "itemsize": itemsize}
    )  # fmt: skip


_ADC = _view_dtype(8, 40)
_IMU = _view_dtype(9, 44)

#: Row names of the matrices built by copying (fields x samples, float64).
GPS_ROWS = ("state", "longitude", "latitude", "altitude", "speed", "track", "climb")
COMPUTER_ROWS = (
    "state", "cpu_temperature", "load1", "load5", "load15",
    "cpu_user", "cpu_sys", "cpu_nice", "cpu_idle", "cpu_iowait", "cpu_hirq", "cpu_sirq",
    "mem_used", "mem_free", "mem_buffers",
)  # fmt: skip
BATTERY_ROWS = (
    "vtotal", "current", "n_cells", *(f"vcell{i}" for i in range(8)), "state", "state_of_charge",
)  # fmt: skip
#: ``info`` of a laser reading: from the last scan, in the original client's order.
HOKUYO_INFO = ("angle_min", "angle_max", "angle_increment", "range_min", "range_max",
               "time_increment")  # fmt: skip


@dataclass
class Reading:
    """The samples of one pull of one sensor.

    ``data`` is shaped as the original ros4mat client returns it (fields x samples: 8 x N
    ADC, 9 x N IMU, 7 x N GPS with longitude first, 15 x N computer, 13 x N battery; images
    H x W x 3 x N; laser ranges x N). ``t`` (N,) are acquisition times on the client's clock
    (or the hub's, see :class:`~robocli.devices.hub.client.Hub`), ``hub_t`` on the hub's.
    Named rows and extra arrays are attributes: ``reading.accel`` (3 x N), ``.gyro``,
    ``.mag``, ``.longitude``, ``.ranges``, ``.depth``, ``.right``... (:attr:`fields` lists
    them). ``data, t = reading`` unpacks like the MATLAB call. Arrays over an uncompressed
    reply are read-only views of the received bytes. ``lost``: samples missing before and
    between this reading's samples, from gaps in their times (set by
    :meth:`~robocli.devices.hub.client.Hub.read`; the hub dropped them when this client's buffer
    overflowed between pulls).
    """

    sensor: str
    data: np.ndarray[Any, Any]
    t: np.ndarray[Any, Any]
    hub_t: np.ndarray[Any, Any]
    packet_timestamp: float = 0.0
    info: np.ndarray[Any, Any] | None = None
    fields: dict[str, np.ndarray[Any, Any]] = field(default_factory=dict)
    nbytes: int = 0
    lost: int = 0

    def __iter__(self) -> Any:
        yield self.data
        yield self.t

    def __len__(self) -> int:
        return int(self.t.shape[0])

    def __getattr__(self, name: str) -> Any:
        fields = self.__dict__.get("fields", {})
        if name in fields:
            return fields[name]
        raise AttributeError(f"{self.__dict__.get('sensor', 'reading')} has no field {name!r}")


def body_of(frame: bytes) -> tuple[tuple[Any, ...], bytes | memoryview]:
    """The parsed header of a reply and its body, inflated when compressed (bounded).
    An error reply raises :class:`DeviceError` with the hub's text."""
    if len(frame) < HEADER_SIZE:
        raise ProtocolError(f"ros4mat reply of {len(frame)} bytes, shorter than its header")
    header = HEADER.unpack_from(frame, 0)
    mtype, error, _cid, size, usize, csize, ctype, _ts = header
    payload = memoryview(frame)[HEADER_SIZE:]
    if len(payload) != csize and (error or size):
        raise ProtocolError(
            f"ros4mat {_name(mtype)}: {len(payload)} body bytes, header says {csize}"
        )
    if error:
        text = bytes(payload).split(b"\0", 1)[0].decode("ascii", "replace")
        what = _REQUEST_OF.get(mtype, _name(mtype))
        raise DeviceError(f"hub refused {what}: {text or 'error ' + str(error)}", error)
    if size == 0 or not len(payload):
        return header, b""
    if ctype == Compression.ZLIB:
        return header, inflate(bytes(payload), usize, what=f"ros4mat {_name(mtype)} body")
    if ctype != Compression.NONE or usize != csize:
        raise ProtocolError(f"ros4mat {_name(mtype)}: bad compression fields {ctype}/{usize}")
    return header, payload


#: An error reply has the type of the expected reply: the request it refuses, by name.
_REQUEST_OF: dict[int, str] = {
    MsgType.CONNECT_ACK: "CONNECT",
    MsgType.SUBSCRIBE_ACK: "SUBSCRIBE",
    MsgType.SERIAL_ANS: "SERIAL_CMD",
    MsgType.SERIAL_OPEN_ACK: "SERIAL_OPEN",
    MsgType.SERIAL_DATA: "the serial stream",
}


def _name(mtype: int) -> str:
    try:
        return MsgType(mtype).name
    except ValueError:
        return f"0x{mtype & 0xFF:02x}"


def _records(body: Any, dtype: np.dtype[Any], n: int, what: str) -> np.ndarray[Any, Any]:
    if len(body) != n * dtype.itemsize:
        raise ProtocolError(
            f"ros4mat {what}: {len(body)} body bytes for {n} records of {dtype.itemsize}"
        )
    return np.frombuffer(body, dtype=dtype, count=n)


def _copy_rows(rec: np.ndarray[Any, Any], cols: list[tuple[str, int | None]]) -> Any:
    out = np.empty((len(cols), rec.shape[0]), dtype=np.float64)
    with np.errstate(invalid="ignore"):  # a signalling NaN from the hub stays a NaN, quietly
        for row, (name, index) in enumerate(cols):
            out[row] = rec[name] if index is None else rec[name][:, index]
    return out


def _fixed(mtype: MsgType, body: Any, n: int) -> tuple[Any, Any, dict[str, Any], Any]:
    """data, hub_t, named fields, info of a fixed-record reply."""
    what = mtype.name
    if mtype == MsgType.ADC:
        rec = _records(body, _ADC, n, what)
        data = rec["v"].T
        return data, rec["t"], {"channels": data}, None
    if mtype == MsgType.IMU:
        rec = _records(body, _IMU, n, what)
        data = rec["v"].T
        named = {"accel": data[0:3], "gyro": data[3:6], "mag": data[6:9]}
        return data, rec["t"], named, None
    rec = _records(body, record_dtype(mtype), n, what)
    if mtype == MsgType.GPS:
        cols: list[tuple[str, int | None]] = [(name, None) for name in GPS_ROWS]
        data = _copy_rows(rec, cols)
        return data, rec["t"], dict(zip(GPS_ROWS, data, strict=True)), None
    if mtype == MsgType.COMPUTER:
        cols = [("state", None), ("cpu_temperature", None)]
        cols += [("unix_load", i) for i in range(3)] + [("cpu_load", i) for i in range(7)]
        cols += [("memory", i) for i in range(3)]
        data = _copy_rows(rec, cols)
        named = dict(zip(COMPUTER_ROWS, data, strict=True))
        named.update(load=data[2:5], cpu=data[5:12], memory=data[12:15])
        return data, rec["t"], named, None
    # BATTERY (robocli's own record)
    cols = [("vtotal", None), ("current", None), ("n_cells", None)]
    cols += [("vcell", i) for i in range(8)] + [("state", None), ("state_of_charge", None)]
    data = _copy_rows(rec, cols)
    named = dict(zip(BATTERY_ROWS, data, strict=True))
    named["vcell"] = data[3:11]
    return data, rec["t"], named, None


#: The largest image side a reply may declare (ros4mat cameras go up to 1600 x 1200).
MAX_IMAGE_SIDE = 0xFFFF


def _check_dims(w: int, h: int, what: str) -> None:
    if w > MAX_IMAGE_SIDE or h > MAX_IMAGE_SIDE:
        raise ProtocolError(f"ros4mat {what}: a {w}x{h} image (sides up to {MAX_IMAGE_SIDE})")


def _image_block(body: Any, offset: int, infos: Any, what: str) -> tuple[Any, int]:
    """N images of identical raw size laid end to end from ``offset``: (N, H, W, C) view."""
    w, h, c = int(infos["width"][0]), int(infos["height"][0]), int(infos["channels"][0])
    size = int(infos["size_data"][0])
    n = infos.shape[0]
    if any(
        (infos[k] != v).any()
        for k, v in (("size_data", size), ("width", w), ("height", h), ("channels", c))
    ):
        raise ProtocolError(f"ros4mat {what}: frames of different sizes in one reply")
    _check_dims(w, h, what)
    if size != w * h * c:
        raise ProtocolError(f"ros4mat {what}: {size} bytes for a raw {w}x{h}x{c} image")
    if offset + n * size > len(body):
        raise ProtocolError(f"ros4mat {what}: body too short for {n} images of {size} bytes")
    arr = np.frombuffer(body, dtype=np.uint8, count=n * size, offset=offset)
    return arr.reshape(n, h, w, c), offset + n * size


def decode_jpeg(blob: bytes, max_bytes: int = MAX_DECODED_BYTES) -> np.ndarray[Any, Any]:
    """One JPEG frame as an H x W x 3 uint8 array (needs Pillow: ``robocli-robots[camera]``).
    Raises :class:`ProtocolError` for bytes that are not a JPEG image, or one that would
    decode to more than ``max_bytes``."""
    try:
        from PIL import Image  # type: ignore[import-not-found,unused-ignore]
    except ImportError:
        raise DeviceError(
            "the hub sends JPEG frames: install Pillow (pip install 'robocli-robots[camera]') or "
            "subscribe with quality=0 (raw)"
        ) from None
    import io
    import warnings

    try:
        with warnings.catch_warnings():  # Pillow warns of a possible decompression bomb
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            img = Image.open(io.BytesIO(blob), formats=["JPEG"])
        with img:
            width, height = img.size
            if width * height * 3 > max_bytes:
                raise ProtocolError(
                    f"JPEG frame of {width}x{height} exceeds the {max_bytes >> 20} MiB "
                    "a reply's frames may decode to"
                )
            return np.asarray(img.convert("RGB"))
    except ProtocolError:
        raise
    except Exception as exc:
        raise ProtocolError(f"undecodable JPEG frame: {type(exc).__name__}: {exc}") from None


def _decode_jpegs(blobs: Any, what: str) -> np.ndarray[Any, Any]:
    """The JPEG frames of one reply as (N, H, W, 3): all of one size, and at most
    :data:`MAX_DECODED_BYTES` in all."""
    frames: list[np.ndarray[Any, Any]] = []
    left = MAX_DECODED_BYTES
    for blob in blobs:
        frame = decode_jpeg(bytes(blob), left)
        if frames and frame.shape != frames[0].shape:
            raise ProtocolError(
                f"ros4mat {what}: JPEG frames of different sizes in one reply "
                f"({frames[0].shape[1]}x{frames[0].shape[0]}, {frame.shape[1]}x{frame.shape[0]})"
            )
        left -= frame.nbytes
        frames.append(frame)
    return np.stack(frames)


def _images(body: Any, offset: int, infos: Any, what: str) -> tuple[Any, int]:
    """(N, H, W, 3) images from ``offset`` (raw: a view; JPEG: decoded), and the end."""
    if not infos.shape[0]:
        return np.zeros((0, 0, 0, 3), np.uint8), offset
    if not (infos["compression"] != 0).any():
        return _image_block(body, offset, infos, what)
    blobs = []
    for size in infos["size_data"]:
        end = offset + int(size)
        if end > len(body):
            raise ProtocolError(f"ros4mat {what}: body too short for its JPEG frames")
        blobs.append(body[offset:end])
        offset = end
    return _decode_jpegs(blobs, what), offset


def _blobs(mtype: MsgType, body: Any, n: int) -> tuple[Any, Any, dict[str, Any], Any]:
    what = mtype.name
    info_dtype = record_dtype(mtype)
    count = 2 * n if mtype == MsgType.WEBCAM_STEREO else n
    head = count * info_dtype.itemsize
    if len(body) < head:
        raise ProtocolError(f"ros4mat {what}: body shorter than its {count} info records")
    infos = np.frombuffer(body, dtype=info_dtype, count=count)
    if mtype == MsgType.HOKUYO:
        beams = int(infos["size_data"][0]) // 4 if n else 0
        if n and ((infos["size_data"] != beams * 4).any() or len(body) != head + n * beams * 4):
            raise ProtocolError(f"ros4mat {what}: scans of different sizes or a short body")
        ranges = np.frombuffer(body, dtype="<f4", count=n * beams, offset=head)
        data = ranges.reshape(n, beams).T
        info = None
        if n:
            last = infos[-1]
            info = np.array([last[k] for k in HOKUYO_INFO], dtype=np.float64)
        return data, infos["t"], {"ranges": data}, info
    if mtype == MsgType.WEBCAM:
        imgs, _ = _images(body, head, infos, what)
        data = imgs.transpose(1, 2, 3, 0)
        return data, infos["t"], {"images": data}, None
    if mtype == MsgType.WEBCAM_STEREO:
        left, right = infos[0::2], infos[1::2]
        if n and not (infos["compression"] != 0).any():
            pairs, _ = _image_block(body, head, infos, what)
            both = pairs.reshape(n, 2, *pairs.shape[1:])
            lv, rv = both[:, 0].transpose(1, 2, 3, 0), both[:, 1].transpose(1, 2, 3, 0)
        else:
            frames, _ = _images(body, head, infos, what)
            lv, rv = frames[0::2].transpose(1, 2, 3, 0), frames[1::2].transpose(1, 2, 3, 0)
        return lv, left["t"], {"left": lv, "right": rv, "right_t": right["t"]}, None
    # KINECT: per frame an RGB blob then a depth blob
    rgb_i, depth_i = infos["rgb"], infos["depth"]
    if not n:
        empty = np.zeros((0, 0, 3, 0), np.uint8)
        return empty, rgb_i["t"], {"rgb": empty, "depth": np.zeros((0, 0, 0), "<u2")}, None
    ds, dw, dh = (int(depth_i[k][0]) for k in ("size_data", "width", "height"))
    rgb_sizes = rgb_i["size_data"].astype(np.int64)
    _check_dims(dw, dh, what)
    same = all((depth_i[k] == v).all() for k, v in (("size_data", ds), ("width", dw)))
    if not same or ds != dw * dh * 2:
        raise ProtocolError(f"ros4mat {what}: depth frames of different sizes in one reply")
    if len(body) != head + int(rgb_sizes.sum()) + n * ds:
        raise ProtocolError(f"ros4mat {what}: body size does not match its frames")
    if (rgb_i["compression"] != 0).any():  # JPEG RGB: each frame its own size, decoded
        blobs, depths, offset = [], [], head
        for rs in rgb_sizes.tolist():
            blobs.append(body[offset : offset + rs])
            offset += rs
            depths.append(np.frombuffer(body, "<u2", count=dw * dh, offset=offset))
            offset += ds
        rgb = _decode_jpegs(blobs, what)
        depth_frames = np.stack(depths).reshape(n, dh, dw)
    else:  # raw RGB: every frame a view
        rs, w, h = (int(rgb_i[k][0]) for k in ("size_data", "width", "height"))
        _check_dims(w, h, what)
        if (rgb_sizes != rs).any() or rs != w * h * 3:
            raise ProtocolError(f"ros4mat {what}: raw RGB frames of different sizes, or "
                                f"{rs} bytes for a {w}x{h} image")  # fmt: skip
        frame_dt = np.dtype([("rgb", np.uint8, (rs,)), ("depth", "<u2", (dh, dw))])
        frames = np.frombuffer(body, dtype=frame_dt, count=n, offset=head)
        rgb = frames["rgb"].reshape(n, h, w, 3)
        depth_frames = frames["depth"]
    data = rgb.transpose(1, 2, 3, 0)
    depth = depth_frames.transpose(1, 2, 0)
    return data, rgb_i["t"], {"rgb": data, "depth": depth}, None


def decode_reading(frame: bytes, sensor: str, offset: float | None = None) -> Reading:
    """A data reply (one whole frame) as a :class:`Reading`. ``offset`` (hub clock minus
    client clock, seconds) moves ``t`` onto the client's clock; None keeps the hub's."""
    header, body = body_of(frame)
    try:
        mtype = MsgType(header[0])
    except ValueError:
        what = _name(header[0])
        raise ProtocolError(f"ros4mat message id {what} is not a sensor reply") from None
    n = header[3]
    if mtype in (MsgType.ADC, MsgType.IMU, MsgType.GPS, MsgType.COMPUTER, MsgType.BATTERY):
        data, hub_t, named, info = _fixed(mtype, body, n)
    elif mtype in (MsgType.WEBCAM, MsgType.WEBCAM_STEREO, MsgType.HOKUYO, MsgType.KINECT):
        data, hub_t, named, info = _blobs(mtype, body, n)
    else:
        raise ProtocolError(f"ros4mat {mtype.name} is not a sensor reply robocli decodes")
    with np.errstate(invalid="ignore"):  # inf - inf from a hub: NaN, quietly
        t = hub_t if offset is None else hub_t - offset
    return Reading(sensor, data, t, hub_t, header[7], info, named, len(frame))


def align_readings(
    readings: Mapping[str, Reading],
    *,
    rate: float | None = None,
    reference: str | None = None,
    tolerance: float | None = None,
) -> dict[str, Any]:
    """Put readings on one time base (see :meth:`Hub.read_aligned`)."""
    if not readings:
        raise InvalidArgument("align_readings: no readings to align")
    empty = [name for name, r in readings.items() if len(r) == 0]
    if empty:
        raise TimeoutError(f"read_aligned: no samples yet from {', '.join(empty)}")
    if reference is not None:
        ref = np.ascontiguousarray(readings[reference].t, dtype=np.float64)
    else:
        if rate is None or not rate > 0:
            raise InvalidArgument(f"rate must be positive, not {rate!r}")
        start = max(float(r.t[0]) for r in readings.values())
        end = min(float(r.t[-1]) for r in readings.values())
        ref = start + np.arange(max(0, int(math.floor((end - start) * rate)) + 1)) / rate
    step = (1.0 / rate) if rate else float(np.median(np.diff(ref))) if len(ref) > 1 else 1.0
    tol = step if tolerance is None else tolerance
    out: dict[str, Any] = {"t": ref}
    for name, r in readings.items():
        data = r.data
        if sensor_type(r.sensor) in RECORDS:  # fixed records: interpolate each field
            idx, w = align_linear(r.t, ref)
            ok = idx >= 0
            j = np.where(ok, idx, 0)
            j1 = np.minimum(j + 1, data.shape[1] - 1)
            vals = (1 - w) * data[:, j] + w * data[:, j1]
            out[name] = np.where(ok, vals, np.nan)
        else:
            idx = align_nearest(r.t, ref, tol)
            picked = np.take(data, np.where(idx >= 0, idx, 0), axis=data.ndim - 1)  # a copy
            missing = idx < 0
            if missing.any():
                picked[..., missing] = np.nan if data.dtype.kind == "f" else 0
            out[name] = picked
    return out


__all__ = ["HEADER", "Reading", "align_readings", "body_of", "decode_jpeg", "decode_reading"]
