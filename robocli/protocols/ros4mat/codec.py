"""ros4mat packets: encoding, bounded inflation, decoding, NumPy record views.

Part of :mod:`robocli.protocols.ros4mat` (import from there).
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import construct as cs

from robocli.errors import FramingError, ProtocolError
from robocli.protocols import layout
from robocli.protocols.common import DECODE_ERRORS, enum_name, enum_or_int, plain, undecodable
from robocli.protocols.ros4mat.ids import (
    HEADER_SIZE,
    INFLATE_STEP,
    MAX_BODY_SIZE,
    Compression,
    MsgType,
    sensor_type,
)
from robocli.protocols.ros4mat.messages import (
    INFO_RECORDS,
    RECORDS,
    REQUEST_BODIES,
    CameraData,
    Header,
    HokuyoData,
    KinectData,
    SerialAnsReply,
    StereoData,
    body_length,
)

if TYPE_CHECKING:
    import numpy as np

# ------------------------------------------------------------------------------ NumPy views


def struct_dtype(decl: Any, path: str = "struct") -> np.dtype[Any]:
    """A packed NumPy structured dtype with the same layout as a ``construct`` Struct
    (:func:`robocli.protocols.layout.numpy_dtype`; ``TypeError`` for unsupported fields)."""
    return layout.numpy_dtype(decl, path)


_DTYPE_CACHE: dict[int, np.dtype[Any]] = {}


def record_dtype(sensor: str | int) -> np.dtype[Any]:
    """The NumPy dtype of one fixed-size record of a sensor, derived from its declaration.

    ADC, IMU, GPS, COMPUTER, BATTERY give the data record; WEBCAM/WEBCAM_STEREO give
    ``msgCam``, HOKUYO ``msgHokuyo`` and KINECT ``msgKinect`` (the info records that
    precede the blobs). Use with ``np.frombuffer(body, dtype=record_dtype("adc"))``.
    """
    msg_type = sensor_type(sensor)
    cached = _DTYPE_CACHE.get(msg_type)
    if cached is None:
        decl = RECORDS.get(msg_type, INFO_RECORDS.get(msg_type))
        if decl is None:
            raise ProtocolError(f"ros4mat {msg_type.name} has no fixed-size record")
        cached = layout.numpy_dtype(decl, msg_type.name)
        _DTYPE_CACHE[msg_type] = cached
    return cached


# ------------------------------------------------------------------------------ helpers


@dataclass(frozen=True)
class DecodedPacket:
    """One decoded packet.

    ``body`` is ``None`` (no body), a dict (request bodies, serial answer, camera/Kinect/
    Hokuyo replies), a list of record dicts (fixed-record sensors), or ``bytes`` (anything
    undeclared). ``error_text`` is set when the header's ``error`` is non-zero.
    """

    msg_type: int
    client_id: int = 0
    size: int = 0
    body: Any = None
    error: int = 0
    compression_type: int = 0
    packet_timestamp: float = 0.0
    error_text: str | None = None


def encode_packet(
    msg_type: int,
    payload: bytes = b"",
    *,
    client_id: int = 0,
    size: int | None = None,
    error: int = 0,
    compress: bool = False,
    packet_timestamp: float = 0.0,
) -> bytes:
    """One whole packet around an already-serialised ``payload``.

    ``size`` defaults to 1 when there is a payload, else 0 (what the original client sends
    with requests). ``compress`` zlib-deflates the payload (RFC 1950, default level).
    """
    payload = bytes(payload)
    if size == 0 and payload and error == 0:
        raise ProtocolError("a ros4mat packet with size 0 cannot carry a body")
    wire = zlib.compress(payload) if compress and payload else payload
    header = {
        "type": int(msg_type),
        "error": error,
        "client_id": client_id,
        "size": (1 if payload else 0) if size is None else size,
        "uncompress_size": len(payload),
        "compress_size": len(wire),
        "compression_type": Compression.ZLIB if compress and payload else Compression.NONE,
        "packet_timestamp": packet_timestamp,
    }
    try:
        data: bytes = Header.build(header) + wire
    except cs.ConstructError as exc:
        raise ProtocolError(f"cannot encode ros4mat header: {exc}") from exc
    return data


def encode_request(
    msg_type: int | str, body: Mapping[str, Any] | bytes | None = None, *, client_id: int = 0
) -> bytes:
    """A client request as the original client sends it.

    ``msg_type`` is a :class:`MsgType` or a sensor name (a data pull, header only).
    ``body`` is a dict of the request's fields (CONNECT, SUBSCRIBE, UNSUBSCRIBE, SERIAL_CMD,
    DOUT_CTRL) or raw bytes; ``None`` for QUIT and data pulls. For SUBSCRIBE, ``params`` is a
    dict of the sensor's params, raw bytes, or ``None`` (silent subscribe); ``params_size``
    is computed.
    """
    kind = sensor_type(msg_type) if isinstance(msg_type, str) else MsgType(msg_type)
    if body is None:
        payload = b""
    elif isinstance(body, (bytes, bytearray)):
        payload = bytes(body)
    else:
        decl = REQUEST_BODIES.get(kind)
        if decl is None:
            raise ProtocolError(f"ros4mat {kind.name} takes no body")
        values = dict(body)
        if kind == MsgType.SUBSCRIBE:
            values.setdefault("params", None)
            values["sensor"] = sensor_type(values["sensor"])
        elif kind == MsgType.UNSUBSCRIBE:
            values["sensor"] = sensor_type(values["sensor"])
        try:
            payload = decl.build(values)
        except (cs.ConstructError, KeyError) as exc:
            raise ProtocolError(f"cannot encode ros4mat {kind.name}: {exc}") from exc
    return encode_packet(kind, payload, client_id=client_id)


def encode_records(
    msg_type: int | str,
    records: Sequence[Mapping[str, Any]],
    *,
    client_id: int = 0,
    packet_timestamp: float = 0.0,
    compress: bool = False,
) -> bytes:
    """A data reply of fixed-size records (ADC, IMU, BATTERY, GPS, COMPUTER)."""
    kind = sensor_type(msg_type)
    decl = RECORDS.get(kind)
    if decl is None:
        raise ProtocolError(f"ros4mat {kind.name} replies are not fixed-size records")
    try:
        payload = b"".join(decl.build(r) for r in records)
    except (cs.ConstructError, KeyError) as exc:
        raise ProtocolError(f"cannot encode ros4mat {kind.name} record: {exc}") from exc
    return encode_packet(
        kind,
        payload,
        client_id=client_id,
        size=len(records),
        compress=compress,
        packet_timestamp=packet_timestamp,
    )


def encode_error(msg_type: int, text: str, *, client_id: int = 0) -> bytes:
    """An error reply: header with ``error = 1`` and a NUL-terminated ASCII text.

    ``msg_type`` is the request's type byte, signed (the header's ``char``) or as read from
    the wire (0-255): a reply to an unknown request type 0x80-0xFF names the same byte."""
    raw = text.encode("ascii", "replace") + b"\0"
    header = {
        "type": (int(msg_type) + 128) % 256 - 128,
        "error": 1,
        "client_id": client_id,
        "size": 0,
        "uncompress_size": len(raw),
        "compress_size": len(raw),
        "compression_type": Compression.NONE,
        "packet_timestamp": 0.0,
    }
    data: bytes = Header.build(header) + raw
    return data


def _decode_body(kind: int, size: int, payload: bytes) -> Any:
    if not payload:
        return None
    if kind in REQUEST_BODIES:
        decl = REQUEST_BODIES[kind]
        return plain(decl.parse(payload))
    if kind in RECORDS:
        rec = RECORDS[kind]
        if len(payload) != size * rec.sizeof():
            raise ProtocolError(
                f"ros4mat {MsgType(kind).name}: {len(payload)} body bytes for {size} records "
                f"of {rec.sizeof()}"
            )
        return plain(cs.Array(size, rec).parse(payload))
    complex_bodies: dict[int, Any] = {
        MsgType.WEBCAM: CameraData,
        MsgType.WEBCAM_STEREO: StereoData,
        MsgType.KINECT: KinectData,
        MsgType.KINECT_DEPTH: KinectData,
        MsgType.HOKUYO: HokuyoData,
        MsgType.SERIAL_ANS: SerialAnsReply,
    }
    decl = complex_bodies.get(kind)
    if decl is None:
        return payload
    if kind == MsgType.SERIAL_ANS:
        return plain(decl.parse(payload))
    return plain(decl.parse(payload, size=size))


def inflate(data: bytes, size: int, *, what: str = "ros4mat body") -> bytes:
    """Inflate a zlib (RFC 1950) body that must give exactly ``size`` bytes.

    Bounded: zlib runs in steps of at most :data:`INFLATE_STEP` output bytes and the body is
    refused as soon as its output exceeds ``size`` (itself at most :data:`MAX_BODY_SIZE`), so
    a small compressed body declaring a small size cannot grow memory beyond that size (a
    "zlib bomb"). Raises :class:`ProtocolError` for a bomb, a corrupt or truncated stream, or
    an output of another size.
    """
    if not 0 <= size <= MAX_BODY_SIZE:
        raise ProtocolError(f"{what}: declared size {size} outside 0..{MAX_BODY_SIZE}")
    inflater = zlib.decompressobj()
    out = bytearray()
    pending = data
    try:
        while not inflater.eof:
            # max_length >= 1 (0 would mean "no limit"): one byte past `size` proves a bomb
            piece = inflater.decompress(pending, min(INFLATE_STEP, size + 1 - len(out)))
            out += piece
            if len(out) > size:
                raise ProtocolError(f"{what}: inflates past its declared {size} bytes")
            stalled = not piece and len(inflater.unconsumed_tail) == len(pending)
            pending = inflater.unconsumed_tail
            if stalled:
                break
    except zlib.error as exc:
        raise ProtocolError(f"{what}: zlib stream does not inflate: {exc}") from exc
    if not inflater.eof:
        raise ProtocolError(f"{what}: zlib stream truncated after {len(out)} bytes")
    if len(out) != size:
        raise ProtocolError(f"{what}: inflated to {len(out)} bytes, header says {size}")
    return bytes(out)


def decode(frame: bytes | bytearray | memoryview) -> DecodedPacket:
    """Decode one whole packet (header + body), inflating a zlib body (bounded, see
    :func:`inflate`).

    Raises :class:`FramingError` when the frame's length does not match its header and
    :class:`ProtocolError`, naming the message, when the body does not match its
    declaration.
    """
    frame = bytes(frame)
    if len(frame) < HEADER_SIZE:
        raise FramingError(f"ros4mat packet of {len(frame)} bytes is shorter than its header")
    try:
        header = Header.parse(frame[:HEADER_SIZE])
    except DECODE_ERRORS as exc:
        undecodable("ros4mat header", frame, exc)
    n = body_length(header)
    if n > MAX_BODY_SIZE:
        raise FramingError(f"ros4mat body of {n} bytes exceeds {MAX_BODY_SIZE}")
    if len(frame) != HEADER_SIZE + n:
        raise FramingError(
            f"ros4mat header announces {n} body bytes, the frame has {len(frame) - HEADER_SIZE}"
        )
    payload = frame[HEADER_SIZE:]
    what = f"ros4mat {enum_name(MsgType, header.type, str(header.type))}"
    common: dict[str, Any] = {
        "msg_type": enum_or_int(MsgType, header.type),
        "client_id": header.client_id,
        "size": header.size,
        "error": header.error,
        "compression_type": header.compression_type,
        "packet_timestamp": header.packet_timestamp,
    }
    if header.error != 0:
        text = payload.split(b"\0", 1)[0].decode("ascii", "replace")
        return DecodedPacket(body=None, error_text=text, **common)
    if header.compression_type == Compression.ZLIB and payload:
        payload = inflate(payload, header.uncompress_size, what=f"{what} body")
    elif header.compression_type not in (Compression.NONE, Compression.ZLIB):
        raise ProtocolError(f"{what}: compression type {header.compression_type} unknown")
    elif header.uncompress_size != header.compress_size and payload:
        raise ProtocolError(
            f"{what}: uncompressed body with uncompress_size {header.uncompress_size} != "
            f"compress_size {header.compress_size}"
        )
    try:
        body = _decode_body(header.type, header.size, payload)
    except DECODE_ERRORS as exc:
        undecodable(f"{what} body", payload, exc)
    return DecodedPacket(body=body, **common)


def adc_freq_send_default(freq: int) -> int:
    """The original client's default ``freqSend`` for a capture rate (not clamped)."""
    return math.floor(freq / 4 + 10)
