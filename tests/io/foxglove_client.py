"""A Foxglove WebSocket client for the tests, written from the protocol's specification
(foxglove/ws-protocol, ``docs/spec.md``), not from the SDK: it offers the subprotocols
``foxglove.websocket.v1`` and ``foxglove.sdk.v1`` (the same protocol under the SDK's name),
reads ``serverInfo`` and ``advertise``, subscribes, and decodes the binary Message Data
frames (opcode 1: subscription id u32, log time u64, payload; little-endian) with the
schema the server advertised for the channel."""

from __future__ import annotations

import contextlib
import json
import struct
import time
from dataclasses import dataclass
from typing import Any

from websockets.sync.client import ClientConnection, connect

from tests.io.readback import viewer_checked

SUBPROTOCOLS = ("foxglove.websocket.v1", "foxglove.sdk.v1")
MESSAGE_DATA = 0x01
KEPT = 64  #: messages kept for each subscription until they are taken


@dataclass
class Channel:
    id: int
    topic: str
    encoding: str
    schema_name: str
    schema_encoding: str
    schema: dict[str, Any]


class FoxgloveClient:
    """``with FoxgloveClient(url) as c:`` connected, ``c.server_info`` read. ``max_queue``:
    the frames the connection's own thread receives ahead of the reader (then it stops
    reading from the socket); ``close_timeout``: how long closing waits for the server's
    close frame (which a client that stopped reading may never get)."""

    def __init__(self, url: str, timeout: float = 30.0, max_queue: int = 16,
                 close_timeout: float = 10.0) -> None:  # fmt: skip
        self.timeout = timeout
        self._stack = contextlib.ExitStack()
        self.ws: ClientConnection = self._stack.enter_context(
            connect(
                url,
                subprotocols=list(SUBPROTOCOLS),
                open_timeout=timeout,  # type: ignore[arg-type]
                max_queue=max_queue,
                max_size=None,
                close_timeout=close_timeout,
            )
        )
        self.channels: dict[int, Channel] = {}
        self.subscriptions: dict[int, int] = {}  # subscription id -> channel id
        #: by subscription, the messages received and not yet taken (its first KEPT)
        self.pending: dict[int, list[tuple[int, bytes]]] = {}
        self.server_info = self._next_json("serverInfo")

    def __enter__(self) -> FoxgloveClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self._stack.close()

    def _recv(self, deadline: float) -> str | bytes:
        left = deadline - time.monotonic()
        if left <= 0:
            raise AssertionError("timed out waiting for the server")
        return self.ws.recv(timeout=left)

    def _handle(self, frame: str | bytes) -> dict[str, Any] | None:
        """Keep binary message data and advertised channels; return a JSON message."""
        if isinstance(frame, bytes):
            assert frame[0] == MESSAGE_DATA, f"opcode {frame[0]}"
            sub, log_ns = struct.unpack_from("<IQ", frame, 1)
            kept = self.pending.setdefault(sub, [])
            if len(kept) < KEPT:  # a latched model comes once: kept while another is read
                kept.append((log_ns, frame[13:]))
            return None
        msg: dict[str, Any] = json.loads(frame)
        if msg["op"] == "advertise":
            for ch in msg["channels"]:
                schema = json.loads(ch["schema"]) if ch.get("schemaEncoding") == "jsonschema" \
                    else {}  # fmt: skip
                self.channels[ch["id"]] = Channel(ch["id"], ch["topic"], ch["encoding"],
                                                  ch["schemaName"], ch.get("schemaEncoding", ""),
                                                  schema)  # fmt: skip
        return msg

    def _next_json(self, op: str) -> dict[str, Any]:
        deadline = time.monotonic() + self.timeout
        while True:
            msg = self._handle(self._recv(deadline))
            if msg is not None and msg["op"] == op:
                return msg

    def wait_for_topics(self, topics: set[str]) -> dict[str, Channel]:
        """Read until every topic of ``topics`` is advertised; the channels by topic."""
        deadline = time.monotonic() + self.timeout
        while not topics <= {c.topic for c in self.channels.values()}:
            self._handle(self._recv(deadline))
        return {c.topic: c for c in self.channels.values()}

    def subscribe(self, channel: Channel) -> int:
        sub = len(self.subscriptions) + 1
        self.subscriptions[sub] = channel.id
        request = json.dumps(
            {"op": "subscribe", "subscriptions": [{"id": sub, "channelId": channel.id}]}
        )
        self.ws.send(request)
        return sub

    def messages(self, sub: int, n: int) -> list[tuple[int, Any]]:
        """The next ``n`` messages of subscription ``sub``: (log time ns, JSON payload),
        each checked against its channel's advertised JSON schema, as a viewer takes it
        (:func:`~tests.io.readback.viewer_checked`)."""
        channel = self.channels[self.subscriptions[sub]]
        deadline = time.monotonic() + self.timeout
        out: list[tuple[int, Any]] = []
        while len(out) < n:
            kept = self.pending.get(sub, [])
            while kept and len(out) < n:
                log_ns, payload = kept.pop(0)
                data = viewer_checked(
                    channel.schema_name, channel.schema, json.loads(payload), channel.topic
                )
                out.append((log_ns, data))
            if len(out) < n:
                self._handle(self._recv(deadline))
        return out
