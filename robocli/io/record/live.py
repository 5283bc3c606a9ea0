"""The live view: the recordings' channels served as they come over the Foxglove WebSocket
protocol (:mod:`robocli.io.record.wsserver`, on ``websockets``: ``pip install
'robocli-robots[foxglove]'``).

>>> from robocli.io.record.live import LiveView             # doctest: +SKIP
>>> with LiveView(port=8765) as view:                       # ws://127.0.0.1:8765 in Foxglove
...     view.add(robot)                                     # a Pioneer, an Arm, a Hub

A :class:`LiveView` is a :class:`~robocli.io.record.links.Sink`: the device recorders that
map frames to Foxglove's schemas for an MCAP file (:mod:`robocli.io.record.sources`) feed it
the same way, so the live channels are the recording's channels, with the same topics,
schemas (``jsonschema``) and JSON messages. Raw-bytes channels are not served (a file keeps
them). It has its own bounded queue and decoding thread, like the
:class:`~robocli.io.record.Recorder`: a device's listener only appends.

While recording, :meth:`Recorder.mirror(view) <robocli.io.record.Recorder.mirror>` has the
recorder's thread hand every decoded message to the view too, so the devices are decoded
once for both.

The server binds 127.0.0.1 unless given another host, serves ``max_clients`` clients at most
and holds at most ``max_client_bytes`` for them all: a client that does not read loses
messages (counted) and, silent for ``stall_s``, its connection; the others' data and the
memory are never its to take (see :mod:`~robocli.io.record.wsserver`).
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any

from robocli.closing import in_background
from robocli.errors import InvalidArgument, RobocliError, TransportError
from robocli.io.record.links import RAW_SCHEMA, SinkBase
from robocli.io.schemas import SCHEMAS, schema_bytes

if TYPE_CHECKING:
    from robocli.devices.hub.client import Hub
    from robocli.io.record.wsserver import FoxgloveServer

log = logging.getLogger("robocli.io.record")

__all__ = ["DEFAULT_PORT", "LiveView", "LiveViewError", "follow_hub"]

#: Foxglove's default WebSocket port.
DEFAULT_PORT = 8765
#: How long the decoding thread sleeps when the queue is empty (s): a live view's latency.
_IDLE_S = 0.02


class LiveViewError(RobocliError):
    """The live view could not start (no ``websockets``)."""


def _server_class() -> type[FoxgloveServer]:
    try:
        import websockets.asyncio.server  # noqa: F401 - the optional extra
    except ImportError:
        raise LiveViewError(
            "the live view needs the websockets package: pip install 'robocli-robots[foxglove]'"
        ) from None
    from robocli.io.record.wsserver import FoxgloveServer

    return FoxgloveServer


class LiveView(SinkBase):
    """A Foxglove WebSocket server on ``host:port`` (0: any free port, see :attr:`port`)
    serving the channels of the devices :meth:`add` ed to it, or of a recorder that
    mirrors into it. ``max_queue`` / ``max_queue_bytes``: what may wait for the decoding
    thread before new items are dropped (counted in :attr:`dropped`). ``max_clients``,
    ``max_client_bytes``, ``stall_s``: the server's bounds (its accounting:
    :attr:`server`). Raises :class:`LiveViewError` without ``websockets``,
    :class:`TransportError` when the port cannot be had (in use), :class:`InvalidArgument`
    for a bad port or bound."""

    def __init__(self, host: str = "127.0.0.1", port: int = DEFAULT_PORT, *,
                 name: str = "robocli", max_queue: int = 100_000,
                 max_queue_bytes: int = 64 << 20, max_clients: int = 16,
                 max_client_bytes: int = 128 << 20, stall_s: float = 10.0) -> None:  # fmt: skip
        if not 0 <= port <= 65535:
            raise InvalidArgument(f"the live view's port is 0..65535, not {port}")
        if max_clients < 1 or max_client_bytes < max_clients or not stall_s > 0:
            raise InvalidArgument("max_clients, max_client_bytes and stall_s must be positive")
        server = _server_class()
        self.host = host
        try:
            #: the WebSocket server, with its accounting (clients, queued bytes, drops)
            self.server = server(host, port, name=name, max_clients=max_clients,
                                 max_queued_bytes=max_client_bytes, stall_s=stall_s)  # fmt: skip
        except OSError as exc:
            why = exc.strerror or exc
            raise TransportError(f"cannot serve the live view on {host}:{port}: {why}") from None
        #: the port the server listens on
        self.port: int = self.server.port
        self.max_queue, self.max_queue_bytes = max_queue, max_queue_bytes
        self._queued_bytes = 0
        #: items dropped for a full queue, messages the server refused
        self.dropped = 0
        self.errors = 0
        #: messages handed to the server
        self.messages = 0
        super().__init__()
        self.links: dict[str, Any] = {}
        self._by_topic: dict[str, int] = {}
        self._lock = threading.Lock()
        self._queue: deque[tuple[Callable[..., None], tuple[Any, ...]]] = deque()
        self._closing = False
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        """``ws://HOST:PORT``, what to open in Foxglove."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"ws://{host}:{self.port}"

    # ------------------------------------------------------------------ Sink

    def add(self, device: Any, name: str | None = None, **options: Any) -> str:
        """Serve ``device`` (a Pioneer, an Arm or a Hub) under ``/name/`` (see
        :meth:`Recorder.add <robocli.io.record.Recorder.add>`); returns the name. A hub's
        data is what its replies carry: the program pulls it."""
        from robocli.io.record import sources

        if self._closed:
            raise LiveViewError("the live view is closed")
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="live-view", daemon=True)
            self._thread.start()
        return sources.attach(self, device, name, **options)

    def put(self, handler: Callable[..., None], args: tuple[Any, ...], size: int = 64) -> bool:
        """Queue ``handler(*args)`` for the decoding thread; never blocks (a full queue
        drops, counted)."""
        with self._lock:
            if (self._closing or len(self._queue) >= self.max_queue
                    or self._queued_bytes + size > self.max_queue_bytes):  # fmt: skip
                self.dropped += 1
                return False
            self._queue.append((handler, args))
            self._queued_bytes += size
        return True

    def channel(self, topic: str, schema: str | None, *, encoding: str = "json",
                metadata: dict[str, str] | None = None) -> int:  # fmt: skip
        """The id of ``topic``'s live channel, advertised on first use; -1 for a channel
        the view does not serve (raw bytes, an unknown schema). A channel whose
        ``metadata`` says ``latched`` keeps its last message for clients that subscribe
        later."""
        cid = self._by_topic.get(topic)
        if cid is not None:
            return cid
        if schema is None or schema not in SCHEMAS or encoding != "json" or schema == RAW_SCHEMA:
            self._by_topic[topic] = -1
            return -1
        cid = self._by_topic[topic] = len(self._by_topic) + 1
        latched = (metadata or {}).get("latched") == "true"  # a robot's model
        self.server.advertise(cid, topic, "json", schema, schema_bytes(schema).decode(),
                              latched=latched)  # fmt: skip
        return cid

    def write(self, cid: int, data: bytes, log_ns: int, publish_ns: int | None = None) -> None:
        """Send one message on live channel ``cid`` (nothing for -1), stamped with the
        source's acquisition time when known (``publish_ns``: a hub reply's samples then
        plot at their own times, not all at the reply's), else the receive time. Never
        raises: a recording that mirrors into the view goes on whatever the server does."""
        if cid < 0 or self._closed:
            return
        try:
            self.server.publish(cid, data, log_ns if publish_ns is None else publish_ns)
            self.messages += 1
        except Exception:
            self.errors += 1
            if self.errors == 1:
                log.warning("live view: a message could not be sent", exc_info=True)

    def decode_failed(self, where: str, exc: BaseException) -> None:
        self.errors += 1
        log.debug("live view: %s: %s", where, exc)

    # ------------------------------------------------------------------ thread

    def _run(self) -> None:
        while True:
            with self._lock:
                items, self._queue = self._queue, deque()
                self._queued_bytes = 0
                closing = self._closing
            if not items:
                if closing:
                    return
                time.sleep(_IDLE_S)
            for handler, args in items:
                try:
                    handler(*args)
                except Exception as exc:
                    self.decode_failed(getattr(handler, "__qualname__", str(handler)), exc)

    # ------------------------------------------------------------------ closing

    def close(self, timeout: float = 10.0) -> None:
        """Stop listening to the devices, close the channels and stop the server.
        Idempotent."""
        if not self._close_begins():
            return
        with self._lock:
            self._closing = True
        if self._thread is not None:
            self._thread.join(timeout)
        self.server.stop()

    def __repr__(self) -> str:
        return f"<LiveView {self.url} messages={self.messages}>"


def follow_hub(hub: Hub, done: Callable[[], bool], period: float = 0.1,
               rescan: float = 1.0) -> None:  # fmt: skip
    """Pull, every ``period`` s until ``done()``, every sensor that the hub runs for its
    other clients: a view or recorder added to ``hub`` then shows what the hub acquires,
    starting and changing no sensor. A silent subscription (which a hub accepts only for a
    running sensor) is taken for each; every ``rescan`` s each is dropped and taken again,
    so that it never keeps a sensor running after its last other client left (a hub stops
    a sensor when its last subscriber leaves; ros4mat does not say how many there are):
    the samples of that instant are not shown. The link's errors raise."""
    from robocli.devices.hub.tools import PULLABLE
    from robocli.errors import DeviceError

    if not (period > 0 and rescan > 0):
        raise InvalidArgument("period and rescan must be positive")
    running: set[str] = set()
    next_scan = 0.0
    while not done():
        now = time.monotonic()
        if now >= next_scan:
            next_scan = now + rescan
            for name in sorted(running):
                with contextlib.suppress(DeviceError):  # a hub that answers refusals
                    hub.unsubscribe(name)
            running.clear()
            for name in PULLABLE:
                try:
                    hub.subscribe(name)
                except DeviceError:
                    continue  # not running
                running.add(name)
        for name in sorted(running):
            try:
                hub.pull(name)
            except DeviceError:  # stopped since: look for it again at the next scan
                running.discard(name)
        time.sleep(period)


@contextlib.contextmanager
def following_hub(view: LiveView, host: str, port: int,
                  token: bytes | None = None) -> Iterator[None]:  # fmt: skip
    """Inside, a client of the hub at ``host:port`` follows every sensor it runs for its
    clients (:func:`follow_hub`), in a thread of its own, and ``view`` serves them; the
    thread and the client stop on the way out (the thread joined within 10 s)."""
    from robocli.devices.hub.client import Hub

    hub = Hub.connect(host, port, token=token)
    view.add(hub)

    def follow(stop: threading.Event) -> None:
        try:
            follow_hub(hub, stop.is_set)
        except RobocliError as exc:  # the hub is closing: the view shows nothing more
            if not stop.is_set():
                log.warning("live view: following the hub stopped: %s", exc)

    try:
        with in_background(follow, "hub-live", 10.0):
            yield
    finally:
        hub.close()
