"""ros4mat messages named and decoded (``robocli dump hub``): :func:`describe` for one
frame, and :class:`DumpProxy`, a recording proxy in front of a hub that hands each message of
the sessions it relays to a callback."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from robocli.analysis import proxy
from robocli.analysis.packets import Packet
from robocli.analysis.proxy import Message, RecordingProxy
from robocli.devices.hub.client import NO_HUB_HINT
from robocli.errors import ProtocolError
from robocli.protocols.common import plain
from robocli.protocols.ros4mat import HEADER_SIZE, MsgType, decode

__all__ = ["DumpProxy", "Message", "check_upstream", "decode_packet", "describe"]


def describe(frame: bytes) -> tuple[str, dict[str, Any]]:
    """Name and decoded fields of one ros4mat frame; bulky bodies are summarised."""
    try:
        msg = decode(frame)
    except ProtocolError as exc:
        return "undecodable", {"error": str(exc), "bytes": len(frame)}
    try:
        name = MsgType(msg.msg_type).name
    except ValueError:
        name = f"0x{int(msg.msg_type) & 0xFF:02x}"
    fields: dict[str, Any] = {"client_id": msg.client_id, "size": msg.size}
    if msg.packet_timestamp:
        fields["packet_timestamp"] = msg.packet_timestamp
    if msg.compression_type:
        fields["zlib"] = f"{len(frame) - HEADER_SIZE} B"
    if msg.error_text is not None:
        fields["error"] = msg.error_text
    body = msg.body
    if isinstance(body, list):
        fields["records"] = len(body)
        if body:
            fields["first"] = body[0]
    elif isinstance(body, dict) and "infos" in body:
        fields["infos"] = body["infos"][:2]
        fields["blob_bytes"] = len(frame) - HEADER_SIZE
    elif isinstance(body, dict):
        fields.update({k: v for k, v in plain(body).items() if k != "data"})
        if "data" in body:
            fields["data"] = bytes(body["data"]).hex()
    elif isinstance(body, bytes):
        fields["body"] = body[:32].hex()
    return name, fields


class DumpProxy(RecordingProxy):
    """A transparent TCP proxy in front of a hub that names and decodes every message.

    Clients connect to :attr:`port` (on ``bind``) instead of the hub; bytes pass through
    unchanged in both directions, and each complete ros4mat frame goes to ``on_message``
    (from the pumping threads; its exceptions are the caller's, they end that session).
    The shared :class:`~robocli.analysis.proxy.RecordingProxy` with ros4mat's framer and
    :func:`describe`.
    """

    def __init__(self, upstream: tuple[str, int], on_message: Callable[[Message], None], *,
                 bind: str = "127.0.0.1", port: int = 0,
                 max_clients: int = 8) -> None:  # fmt: skip
        super().__init__(upstream, on_message, framer="ros4mat", describe=describe, bind=bind,
                         port=port, max_clients=max_clients, name="hub-dump")  # fmt: skip


def check_upstream(host: str, port: int, timeout: float = 2.0) -> None:
    """Raise :class:`TransportError` when nothing listens at the hub's address."""
    proxy.check_upstream(host, port, timeout, "hub", NO_HUB_HINT)


def decode_packet(direction: str, frame: bytes, t: float | None) -> Packet:
    """One whole ros4mat frame as a :class:`~robocli.analysis.packets.Packet`."""
    name, fields = describe(frame)
    return Packet(t, direction, name, fields, frame)
