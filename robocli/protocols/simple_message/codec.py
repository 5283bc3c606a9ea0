"""Simple Message frames to and from bytes: :func:`encode`, :func:`decode` (into a
:class:`SimpleMessage`) and the reference library's header rule (:func:`validate_header`).

Part of :mod:`robocli.protocols.simple_message` (import from there).
"""

from __future__ import annotations

import struct
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import construct as cs

from robocli.errors import FramingError, ProtocolError
from robocli.protocols.common import DECODE_ERRORS, enum_name, enum_or_int, plain, undecodable
from robocli.protocols.simple_message.constants import (
    HEADER_SIZE,
    MAX_FRAME_SIZE,
    MAX_LENGTH,
    MIN_LENGTH,
    PREFIX_SIZE,
    CommType,
    ReplyCode,
    SimpleMessageType,
)
from robocli.protocols.simple_message.spec import ByteOrder, RealSize, messages


@dataclass(frozen=True)
class SimpleMessage:
    """One decoded frame. ``body``: ``None`` (header only), a dict, or raw ``bytes``."""

    msg_type: int
    comm_type: int
    reply_code: int
    body: dict[str, Any] | bytes | None = None


def validate_header(msg_type: int, comm_type: int, reply_code: int) -> None:
    """Apply the reference library's header rule, or raise :class:`ProtocolError`.

    ``msg_type != 0``, ``comm_type != 0``, and ``reply_code != 0`` exactly when
    ``comm_type == SERVICE_REPLY``. Nothing else is checked (undefined types, comm types and
    reply codes are legal), exactly like ``SimpleMessage::validateMessage``.
    """
    if msg_type == 0:
        raise ProtocolError("invalid Simple Message header: msg_type is 0 (INVALID)")
    if comm_type == 0:
        raise ProtocolError(
            f"invalid Simple Message header: comm_type is 0 (INVALID), msg_type {msg_type}"
        )
    if comm_type == CommType.SERVICE_REPLY:
        if reply_code == 0:
            raise ProtocolError(
                f"invalid Simple Message header: SERVICE_REPLY with reply_code 0, "
                f"msg_type {msg_type}"
            )
    elif reply_code != 0:
        raise ProtocolError(
            f"invalid Simple Message header: reply_code {reply_code} on comm_type "
            f"{comm_type} (only SERVICE_REPLY may carry one), msg_type {msg_type}"
        )


def encode(
    msg_type: int,
    comm_type: int,
    reply_code: int = 0,
    body: Mapping[str, Any] | bytes | None = None,
    *,
    byteorder: ByteOrder = "<",
    real: RealSize = 4,
) -> bytes:
    """One whole frame (prefix included).

    ``body`` is ``None`` (header only), a dict of the fields of ``msg_type``'s body, or raw
    ``bytes``. Raises :class:`ProtocolError` for a header the reference library would refuse
    to send, an unknown body, or a frame longer than :data:`MAX_FRAME_SIZE`.
    """
    validate_header(msg_type, comm_type, reply_code)
    spec = messages(byteorder, real)
    if isinstance(body, (bytearray, memoryview)):
        body = bytes(body)
    try:
        size = PREFIX_SIZE + HEADER_SIZE + spec.body_size(msg_type, body)
    except (KeyError, TypeError) as exc:
        raise ProtocolError(f"cannot encode Simple Message {msg_type}: {exc!r}") from exc
    if size > MAX_FRAME_SIZE:
        raise ProtocolError(
            f"Simple Message frame of {size} bytes exceeds the {MAX_FRAME_SIZE}-byte limit"
        )
    header = {"msg_type": msg_type, "comm_type": comm_type, "reply_code": reply_code}
    try:
        data: bytes = spec.Frame.build({"header": header, "body": body})
    except (cs.ConstructError, KeyError, TypeError, ValueError) as exc:
        raise ProtocolError(f"cannot encode Simple Message {msg_type}: {exc!r}") from exc
    return data


def decode(
    frame: bytes,
    *,
    byteorder: ByteOrder = "<",
    real: RealSize = 4,
    validate: bool = True,
    max_length: int = MAX_LENGTH,
) -> SimpleMessage:
    """Decode one whole frame (prefix included).

    Raises :class:`FramingError` when the prefix does not match the frame (``length`` < 12,
    > ``max_length``, or not equal to ``len(frame) - 4``) and, with ``validate``,
    :class:`ProtocolError` for a header the reference library rejects.
    """
    frame = bytes(frame)
    if len(frame) < PREFIX_SIZE + HEADER_SIZE:
        raise FramingError(
            f"Simple Message frame of {len(frame)} bytes is shorter than prefix + header (16)"
        )
    (length,) = struct.unpack(byteorder + "i", frame[:PREFIX_SIZE])
    if length < MIN_LENGTH or length > max_length:
        raise FramingError(
            f"Simple Message length prefix {length} outside {MIN_LENGTH}..{max_length}"
        )
    if length != len(frame) - PREFIX_SIZE:
        raise FramingError(
            f"Simple Message length prefix {length} does not match the "
            f"{len(frame) - PREFIX_SIZE} bytes after it"
        )
    spec = messages(byteorder, real)
    try:
        parsed = spec.Frame.parse(frame)
    except DECODE_ERRORS as exc:
        (msg_type,) = struct.unpack_from(byteorder + "i", frame, PREFIX_SIZE)
        undecodable(
            f"Simple Message {enum_name(SimpleMessageType, msg_type, str(msg_type))}", frame, exc
        )
    header = parsed.header
    if validate:
        validate_header(header.msg_type, header.comm_type, header.reply_code)
    body = parsed.body
    return SimpleMessage(
        msg_type=enum_or_int(SimpleMessageType, header.msg_type),
        comm_type=enum_or_int(CommType, header.comm_type),
        reply_code=enum_or_int(ReplyCode, header.reply_code),
        body=body if body is None or isinstance(body, bytes) else plain(body),
    )
