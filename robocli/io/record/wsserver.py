"""The live view's server: the Foxglove WebSocket protocol (``foxglove.websocket.v1``, the
protocol Foxglove and Lichtblick open as "Foxglove WebSocket"; ``foxglove.sdk.v1`` is the
same under the name the Foxglove SDK gives it), written on the ``websockets`` package so
that what a stranger can make it hold is bounded and counted.

What the protocol needs of a server that only publishes: on connection ``serverInfo``
(JSON), then ``advertise`` of every channel (and of each new one as it comes); a client's
``subscribe`` (``subscriptions``: ``id``, ``channelId``) and ``unsubscribe``
(``subscriptionIds``); each message then goes to each subscription as a binary frame, opcode
``0x01``, the subscription id (u32), the message's time (u64 ns), the payload
(little-endian).

**Bounds.** At most ``max_clients`` connections (one more is refused with HTTP 503 before
its handshake). What waits for the clients, all of them together, is at most
``max_queued_bytes``: each client may hold its share (``max_queued_bytes // max_clients``),
and a message that does not fit a client's share is not queued for it, counted in
:attr:`FoxgloveServer.dropped` (and the client's own count): a client that does not read
loses messages, never the others' data and never memory. A client whose send has not
progressed for ``stall_s`` seconds is disconnected (counted in
:attr:`FoxgloveServer.slow_disconnected`), so that a silent client gives its place back.
Beyond the queues, each connection holds at most the ``websockets`` write buffer's high-water
mark (``_WRITE_LIMIT``) and the few small frames a client may send (``_MAX_REQUEST``).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import struct
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

log = logging.getLogger("robocli.io.record")

__all__ = ["SUBPROTOCOLS", "FoxgloveServer"]

#: The subprotocols served, in the server's order of preference.
SUBPROTOCOLS = ("foxglove.websocket.v1", "foxglove.sdk.v1")
_MESSAGE_DATA = struct.Struct("<BIQ")  # opcode 0x01, subscription id, time (ns)
_WRITE_LIMIT = 1 << 16  #: the websockets write buffer's high-water mark per connection
_MAX_REQUEST = 1 << 16  #: the largest frame a client may send (its requests are small)
_START_TIMEOUT = 10.0


@dataclass
class _Client:
    """One connection: its subscriptions and its queue of frames (bytes accounted)."""

    ws: Any
    name: str
    wake: asyncio.Event
    subs: dict[int, int] = field(default_factory=dict)  # channel id -> subscription id
    queue: deque[bytes | str] = field(default_factory=deque)  # data (bytes), control (str)
    queued: int = 0  #: bytes in ``queue`` and in the frame being sent
    dropped: int = 0  #: messages not queued for a full share
    sent: int = 0
    closed: bool = False
    asleep: bool = False  #: its sender waits for ``wake`` (set it once, not per message)


class FoxgloveServer:
    """A Foxglove WebSocket server on ``host:port`` (0: any free port, see :attr:`port`),
    started at once in its own thread. See the module docstring for the bounds. Raises
    :class:`OSError` when the port cannot be had."""

    def __init__(self, host: str, port: int, *, name: str = "robocli", max_clients: int = 16,
                 max_queued_bytes: int = 128 << 20, stall_s: float = 10.0) -> None:  # fmt: skip
        if max_clients < 1 or max_queued_bytes < 1 or not stall_s > 0:
            raise ValueError("max_clients, max_queued_bytes and stall_s must be positive")
        self.name, self.max_clients, self.stall_s = name, max_clients, stall_s
        self.max_queued_bytes = max_queued_bytes
        #: what one client may hold waiting (bytes)
        self.client_share = max_queued_bytes // max_clients
        self.dropped = 0  #: messages not queued for a client (its share full), all clients
        self.refused = 0  #: connections refused (the server full, no Foxglove subprotocol)
        self.slow_disconnected = 0  #: clients closed for not reading for ``stall_s``
        self.peak_queued = 0  #: the most bytes queued at once, all clients
        self._queued = 0
        self._lock = threading.Lock()
        self._clients: list[_Client] = []
        self._channels: dict[int, dict[str, Any]] = {}
        #: latched channels: their last message (data, ns), None before the first
        self._latched: dict[int, tuple[bytes, int] | None] = {}
        self._session = str(time.time_ns())
        self._loop = asyncio.new_event_loop()
        started = threading.Event()
        failure: list[BaseException] = []
        self._server: Any = None
        self._thread = threading.Thread(target=self._run, args=(host, port, started, failure),
                                        name="live-view-server", daemon=True)  # fmt: skip
        self._thread.start()
        if not started.wait(_START_TIMEOUT) or failure:
            self.stop()
            raise failure[0] if failure else OSError(f"the server did not start on {port}")
        #: the port the server listens on
        self.port: int = self._listening_port()

    def _listening_port(self) -> int:
        return int(self._server.sockets[0].getsockname()[1])

    # ------------------------------------------------------------------ accounting

    @property
    def queued_bytes(self) -> int:
        """Bytes waiting for the clients now, all of them (at most ``max_queued_bytes``)."""
        return self._queued

    @property
    def clients(self) -> int:
        """Connections being served."""
        return len(self._clients)

    def subscribers(self, cid: int) -> int:
        """Clients subscribed to channel ``cid``."""
        with self._lock:
            return sum(cid in c.subs for c in self._clients)

    # ------------------------------------------------------------------ publishing (any thread)

    def advertise(self, cid: int, topic: str, encoding: str, schema_name: str,
                  schema: str, *, latched: bool = False) -> None:  # fmt: skip
        """Make channel ``cid`` known to every client, now and later. ``latched``: its last
        message is kept and sent to each subscription made later (a robot's model, written
        once), as to those there when it came."""
        channel = {"id": cid, "topic": topic, "encoding": encoding, "schemaName": schema_name,
                   "schema": schema, "schemaEncoding": "jsonschema"}  # fmt: skip
        text = json.dumps({"op": "advertise", "channels": [channel]}, separators=(",", ":"))
        with self._lock:
            self._channels[cid] = channel
            if latched:
                self._latched.setdefault(cid, None)
            clients = list(self._clients)
        for client in clients:
            self._control(client, text)

    def publish(self, cid: int, data: bytes, ns: int) -> None:
        """Queue ``data`` (time ``ns``) for every subscription to channel ``cid``; a client
        whose share it does not fit loses it (counted). Never blocks."""
        wake = []
        with self._lock:
            if cid in self._latched:
                self._latched[cid] = (data, ns)
            for client in self._clients:
                sub = client.subs.get(cid)
                if sub is not None and self._queue_data(client, sub, data, ns):
                    wake.append(client)
            self.peak_queued = max(self.peak_queued, self._queued)
        for client in wake:
            self._loop.call_soon_threadsafe(client.wake.set)

    def _queue_data(self, client: _Client, sub: int, data: bytes, ns: int) -> bool:
        """Queue one message for ``client``'s subscription ``sub`` unless its share is full
        (counted); True when its sender must be woken. Holds ``_lock``."""
        if client.closed:
            return False
        size = _MESSAGE_DATA.size + len(data)
        if client.queued + size > self.client_share:
            client.dropped += 1
            self.dropped += 1
            return False
        client.queue.append(_MESSAGE_DATA.pack(1, sub, ns) + data)
        client.queued += size
        self._queued += size
        asleep, client.asleep = client.asleep, False
        return asleep

    def _control(self, client: _Client, frame: str) -> None:
        """Queue a control message (JSON text): never dropped; few and small (one
        ``serverInfo``, one ``advertise`` per channel)."""
        with self._lock:
            client.queue.append(frame)
            asleep, client.asleep = client.asleep, False
        if asleep:
            self._loop.call_soon_threadsafe(client.wake.set)

    # ------------------------------------------------------------------ the server (its thread)

    def _run(self, host: str, port: int, started: threading.Event,
             failure: list[BaseException]) -> None:  # fmt: skip
        asyncio.set_event_loop(self._loop)
        try:
            self._loop.run_until_complete(self._start(host, port))
        except BaseException as exc:
            failure.append(exc)
            self._loop.close()
            started.set()
            return
        started.set()
        try:
            self._loop.run_forever()
        finally:
            self._loop.close()

    async def _start(self, host: str, port: int) -> None:
        from websockets.asyncio.server import serve

        self._server = await serve(
            self._serve, host, port, subprotocols=list(SUBPROTOCOLS),  # type: ignore[arg-type]
            process_request=self._admit, compression=None, max_size=_MAX_REQUEST,
            max_queue=4, write_limit=_WRITE_LIMIT, open_timeout=5, close_timeout=2,
        )  # fmt: skip

    def _admit(self, connection: Any, request: Any) -> Any:
        """Refuse a connection past ``max_clients`` before its handshake."""
        if len(self._clients) >= self.max_clients:
            self.refused += 1
            return connection.respond(503, f"the live view serves {self.max_clients} "
                                      "clients at most\n")  # fmt: skip
        return None

    async def _serve(self, ws: Any) -> None:
        if ws.subprotocol not in SUBPROTOCOLS or len(self._clients) >= self.max_clients:
            self.refused += 1
            await ws.close(1008 if ws.subprotocol not in SUBPROTOCOLS else 1013)
            return
        client = _Client(ws, str(ws.remote_address), asyncio.Event())
        info = {"op": "serverInfo", "name": self.name, "capabilities": [],
                "supportedEncodings": [], "metadata": {}, "sessionId": self._session}  # fmt: skip
        with self._lock:
            self._clients.append(client)
            channels = list(self._channels.values())
        self._control(client, json.dumps(info))
        if channels:
            self._control(client, json.dumps({"op": "advertise", "channels": channels}))
        sender = asyncio.ensure_future(self._send(client))
        try:
            async for request in ws:
                self._request(client, request)
        except Exception as exc:
            log.debug("live view: %s: %s", client.name, exc)
        finally:
            sender.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await sender
            self._forget(client)

    async def _send(self, client: _Client) -> None:
        ws = client.ws
        while True:
            with self._lock:
                frame = client.queue.popleft() if client.queue else None
                if frame is None:  # a publisher that queues from now on wakes it
                    client.asleep = True
                    client.wake.clear()
            if frame is None:
                await client.wake.wait()
                continue
            stalled = False
            try:
                await asyncio.wait_for(ws.send(frame), self.stall_s)
            except asyncio.TimeoutError:
                stalled = True
            finally:  # the frame in flight leaves the count however its send ended
                if isinstance(frame, bytes):
                    with self._lock:
                        client.queued -= len(frame)
                        self._queued -= len(frame)
            if stalled:  # counted once all it held is given back: the two never disagree
                log.info("live view: %s read nothing for %g s: disconnected", client.name,
                         self.stall_s)  # fmt: skip
                self._forget(client)
                self.slow_disconnected += 1
                ws.transport.abort()
                return
            client.sent += 1

    def _request(self, client: _Client, request: str | bytes) -> None:
        """A client's subscribe or unsubscribe; anything else is ignored."""
        try:
            msg = json.loads(request)
            op = msg.get("op")
            if op == "subscribe":
                for sub in msg["subscriptions"]:
                    sid, cid = int(sub["id"]), int(sub["channelId"])
                    with self._lock:
                        if cid in self._channels and 0 <= sid < 1 << 32:
                            client.subs[cid] = sid
                            last = self._latched.get(cid)
                            if last is not None and self._queue_data(client, sid, *last):
                                client.wake.set()  # (this runs on the server's loop)
            elif op == "unsubscribe":
                gone = {int(s) for s in msg["subscriptionIds"]}
                with self._lock:
                    client.subs = {c: s for c, s in client.subs.items() if s not in gone}
        except (ValueError, KeyError, TypeError, AttributeError) as exc:
            log.debug("live view: %s: a request ignored (%s)", client.name, exc)

    def _forget(self, client: _Client) -> None:
        with self._lock:
            if client.closed:
                return
            client.closed = True
            if client in self._clients:
                self._clients.remove(client)
            waiting = sum(len(f) for f in client.queue if isinstance(f, bytes))
            client.queue.clear()
            client.queued -= waiting
            self._queued -= waiting

    # ------------------------------------------------------------------ stopping

    def stop(self, timeout: float = 10.0) -> None:
        """Close every connection and the listening socket; idempotent."""
        if not self._loop.is_closed() and self._loop.is_running():
            if self._server is not None:
                future = asyncio.run_coroutine_threadsafe(self._close(), self._loop)
                with contextlib.suppress(Exception):
                    future.result(timeout)
            self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout)

    async def _close(self) -> None:
        self._server.close()
        with contextlib.suppress(asyncio.TimeoutError):
            await asyncio.wait_for(self._server.wait_closed(), 5)
