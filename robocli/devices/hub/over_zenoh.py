"""The sensor hub over Eclipse Zenoh: :class:`ZenohHub`, a :class:`~robocli.devices.hub.
client.Hub` whose samples come from a hub's Zenoh front-end (``robocli serve --zenoh``).

>>> with ZenohHub.connect("lab-hub", zenoh="tcp/127.0.0.1:7447") as hub:  # doctest: +SKIP
...     hub.subscribe("imu", rate=200)
...     data, t = hub.read("imu")                   # 9 x N, (N,): as over ros4mat TCP

Each subscribed sensor is a Zenoh advanced subscriber on ``robocli/<hub>/<sensor>``: it
gets the hub's recent history when it joins, and Zenoh recovers the batches it missed from
the hub's cache. Batches wait in a bounded queue (``buffer`` samples, as the hub's buffer
over ros4mat) until :meth:`read`, which decodes them with the ros4mat decoder: the same
arrays, shapes and timestamps as :class:`Hub` gives. Samples missing from the sequence
numbers of the batches are counted in :attr:`lost` (and ``Reading.lost``), batches seen twice
are dropped and counted in :attr:`duplicates`; batches that cannot be the hub's (not
batches, another sensor's, a sample count the body cannot hold, a gap in the numbering
larger than the hub could have acquired since the previous batch) are dropped and counted
in :attr:`rejected`, never read. Under a lab router's ACL (:mod:`robocli.zenoh.acl`) only
the hub's user can put on its keys. ``subscribe(name, rate)`` changes the
sensor's settings for everyone through the hub's settings queryable (with the token when
the hub has one); ``subscribe(name)`` joins what is published.
"""

from __future__ import annotations

import json
import math
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from robocli.devices.base import (
    ListenerHandle,
    ZenohPeer,
    pick_kind,
    renamed_argument,
    zenoh_where,
)
from robocli.devices.hub.client import ZENOH_HUB, Hub
from robocli.devices.hub.decode import HEADER, Reading, decode_reading
from robocli.devices.hub.link import token_bytes
from robocli.devices.hub.subscription import subscribe_request
from robocli.devices.listeners import FrameListener, Listeners
from robocli.devices.stats import LinkStats
from robocli.errors import (
    DeviceError,
    InvalidArgument,
    ProtocolError,
    TimeoutError,
    TransportError,
)
from robocli.protocols.ros4mat import MsgType, sensor_type
from robocli.zenoh.batch import BLOBS, Batch, decode_batch, head_size
from robocli.zenoh.keys import (
    ALIVE_ALL,
    alive_key,
    check_name,
    info_key,
    parse_alive,
    settings_key,
    topic_key,
)
from robocli.zenoh.payload import decode_object
from robocli.zenoh.session import (
    DEFAULT_ENDPOINT,
    ZenohTarget,
    close_session,
    import_zenoh,
    open_session,
)

if TYPE_CHECKING:
    import zenoh

__all__ = ["HUB_NAMES", "ZenohHub", "alive", "hub_name_of"]

HUB_NAMES: dict[MsgType, str] = {
    MsgType.ADC: "adc", MsgType.IMU: "imu", MsgType.BATTERY: "battery", MsgType.GPS: "gps",
    MsgType.WEBCAM: "camera", MsgType.COMPUTER: "sysinfo", MsgType.HOKUYO: "laser",
    MsgType.KINECT: "depth", MsgType.WEBCAM_STEREO: "stereo",
}  # fmt: skip
"""A sensor's ros4mat id -> its name on the hub (and in its Zenoh key)."""
MAX_REPLY = 16 << 20  #: the largest @info or @settings reply decoded (bytes)
HISTORY_BATCHES = 1 << 10  #: the most batches of history a joining subscriber asks for
HISTORY_SHARE = 0.5
"""A joining subscriber asks for the history that fills this share of its buffer (the
rest leaves room for the live samples arriving before the first read)."""
GAP_MARGIN = 2.0
"""A gap in the numbering may be this many times what the hub acquires at the sensor's
rate between two batches' stamps (plus the reader's buffer), not more."""


def hub_name_of(sensor: str) -> str:
    """The hub's name for ``sensor`` (an alias such as ``hokuyo`` or ``computer`` too)."""
    kind = sensor_type(sensor)
    if kind not in HUB_NAMES:
        raise InvalidArgument(f"sensor {sensor!r} is not published over Zenoh")
    return HUB_NAMES[kind]


def alive(session: zenoh.Session, timeout: float = 2.0) -> list[tuple[str, str]]:
    """``(name, kind)`` of every robocli server up (its liveliness token), sorted."""
    found = set()
    for reply in session.liveliness().get(ALIVE_ALL, timeout=timeout):
        if reply.ok is not None:
            parsed = parse_alive(str(reply.ok.key_expr))
            if parsed is not None:
                found.add(parsed)
    return sorted(found)


class _Queue:
    """The batches of one sensor waiting for :meth:`ZenohHub.read` (at most ``limit``
    samples: the oldest go first, counted); a payload that is not a batch of ``kind`` is
    rejected (counted)."""

    def __init__(self, limit: int, kind: MsgType) -> None:
        self.limit = max(1, limit)
        self.kind = kind
        self.items: deque[tuple[Batch, bytes]] = deque()
        self.samples = 0
        self.overflow = 0  # samples dropped because nobody read them in time
        self.errors = 0  # payloads that were not batches of this sensor
        self.lock = threading.Lock()

    def push(self, payload: bytes) -> None:
        try:
            batch = decode_batch(payload)
        except ProtocolError:
            batch = None
        if batch is None or batch.sensor_id != int(self.kind):
            with self.lock:
                self.errors += 1
            return
        with self.lock:
            self.items.append((batch, payload))
            self.samples += batch.count
            while self.samples > self.limit and len(self.items) > 1:
                old, _ = self.items.popleft()
                self.samples -= old.count
                self.overflow += old.count

    def take(self) -> list[Batch]:
        with self.lock:
            out = [b for b, _ in self.items]
            self.items.clear()
            self.samples = 0
        return out


class ZenohHub(ZenohPeer, Hub):
    """A client of a hub's Zenoh front-end: :class:`Hub`'s reading API over Zenoh.

    Not over Zenoh: :meth:`pull` (raw ros4mat frames), :meth:`serial`,
    :meth:`digital_out`; they raise :class:`DeviceError`."""

    def __init__(
        self,
        zsession: zenoh.Session,
        name: str,
        *,
        timeout: float,
        clock: Callable[[], float],
        hub_clock: bool,
        token: bytes | None,
        history: bool = True,
    ) -> None:
        self.zsession = zsession
        self.name = check_name(name, "hub name")
        self.timeout, self.clock, self.hub_clock = timeout, clock, hub_clock
        self.client_id, self.compress, self.answers_refusals = 0, False, True
        self.history = history
        from robocli.devices.hub.clock import ClockSync

        self.sync = ClockSync()
        self._token = token
        self._subscribed: dict[str, MsgType] = {}
        self._lost: dict[str, int] = {}
        self._queues: dict[str, _Queue] = {}
        self._subs: dict[str, Any] = {}
        self._next: dict[str, int] = {}  # the sequence number expected next, per sensor
        self._stamp: dict[str, float] = {}  # when the last batch taken was put (hub clock)
        self.duplicates: dict[str, int] = {}
        """Batches received twice (history overlapping live samples), by sensor: dropped."""
        self.missed: dict[str, int] = {}
        """Batches Zenoh's miss detection reported lost for good, by sensor."""
        self.rejected: dict[str, int] = {}
        """Batches that cannot be the hub's (see the module), by sensor: dropped."""
        self._hz: dict[str, float] = {}  # each sensor's rate when subscribed
        self._stats = LinkStats()  # batches received, by sensor
        self._frames: Listeners[FrameListener] = Listeners(self._stats, f"zenoh/{self.name}")
        self._gone: str | None = None  # why the hub is gone (its liveliness token went)
        self._alive_sub = zsession.liveliness().declare_subscriber(
            alive_key(self.name, "hub"), self._on_alive, history=True
        )

    def _on_alive(self, sample: Any) -> None:
        """The hub's liveliness token: gone, or (a hub restarted under the name) back."""
        if sample.kind == import_zenoh().SampleKind.DELETE:
            self._gone = f"the hub {self.name} left (its liveliness token went)"
        else:
            self._gone = None

    def _received(self, queue: _Queue, key: str, payload: bytes) -> None:
        self._stats.count_received(key)
        self._frames.notify("rx", payload, time.monotonic())
        queue.push(payload)

    @classmethod
    def connect(  # type: ignore[override]
        cls,
        name: str | None = None,
        *,
        zenoh: str | ZenohTarget | None = None,
        timeout: float = 5.0,
        clock: Callable[[], float] = time.time,
        hub_clock: bool = False,
        token: bytes | str | None = None,
        history: bool = True,
    ) -> ZenohHub:
        """Connect to the hub ``name`` (``zenoh/NAME`` too, ``zenoh/NAME?zenoh=ENDPOINT``
        with the endpoint in the URL; None: the one hub that is up) through the Zenoh
        endpoint or configuration ``zenoh`` (default tcp/127.0.0.1:7447), and ask what it
        serves. ``token``: the hub's token, needed to
        change settings on a hub that has one. ``history``: a subscription starts with the
        hub's recent batches. Raises :class:`TransportError` when nothing answers there,
        :class:`TimeoutError` when no hub of that name answers."""
        secret = token_bytes(token) or None
        if name is not None:
            name, zenoh = zenoh_where(name, zenoh, "hub")
        session = open_session(zenoh, "client")
        try:
            if name is None:
                hubs = [n for n, kind in alive(session, timeout) if kind == "hub"]
                if not hubs:
                    raise TransportError(f"no hub is up on Zenoh at {zenoh or DEFAULT_ENDPOINT}")
                if len(hubs) > 1:
                    raise InvalidArgument(f"give the hub's name: {', '.join(hubs)} are up")
                name = hubs[0]
            hub = cls(session, name.removeprefix("zenoh/"), timeout=timeout, clock=clock,
                      hub_clock=hub_clock, token=secret, history=history)  # fmt: skip
            hub.info()
        except BaseException:
            close_session(session)
            raise
        return hub

    # ------------------------------------------------------------------ queries

    def _query(self, key: str, payload: str | None = None) -> Any:
        """The one reply to a query of ``key`` (its JSON); an error reply raises
        :class:`DeviceError`, no reply :class:`TimeoutError`."""
        replies = self.zsession.get(key, payload=payload, timeout=self.timeout)
        for reply in replies:
            if reply.ok is not None:
                return decode_object(reply.ok.payload.to_bytes(), f"{key} reply", MAX_REPLY)
            raw = reply.err.payload.to_bytes() if reply.err is not None else b""
            try:
                error = decode_object(raw, f"{key} error", MAX_REPLY)
                text = str(error.get("error", error))[:500]
            except ProtocolError:  # not the hub's JSON: its first bytes as text
                text = raw[:500].decode("utf-8", "replace")
            raise DeviceError(f"hub {self.name} refused: {text}")
        self.check()  # nobody answered: because the hub left (ConnectionLost)?
        raise TimeoutError(f"no hub named {self.name!r} answers on Zenoh ({key})")

    def info(self) -> dict[str, Any]:
        """What the hub serves (``robocli/<hub>/@info``): its sensors, their settings,
        whether each is published. Also a clock sample (the reply carries the hub's time)."""
        t0 = self.clock()
        info: dict[str, Any] = self._query(info_key(self.name))
        t1 = self.clock()
        if isinstance(info.get("clock"), (int, float)):
            self.sync.add(t0, t1, float(info["clock"]))
        return info

    # ------------------------------------------------------------------ sensors

    def subscribe(
        self,
        name: str,
        rate: float | None = None,
        *,
        buffer: int | None = None,
        poll: int | None = None,
        **params: Any,
    ) -> None:
        """As :meth:`Hub.subscribe`: with ``rate``, the sensor's settings change for
        everyone (the hub's settings queryable; :class:`DeviceError` "unauthorized"
        without the token on a hub that has one); without, join what is published.
        ``buffer``: samples kept here between reads (default: one second's)."""
        sensor = hub_name_of(name)
        key = name.lower()
        if rate is not None:
            body = subscribe_request(name, rate, buffer=buffer, poll=poll, **params)
            request: dict[str, Any] = {"params": body["params"]}
            if self._token is not None:
                request["token"] = self._token.decode("utf-8", "replace")
            settings = self._query(settings_key(self.name, sensor), json.dumps(request))
        else:
            settings = self.info().get("sensors", {}).get(sensor, {})
            if not settings.get("published"):
                raise DeviceError(f"hub {self.name} does not publish {sensor}: give a rate")
        hz = max(1e-3, float(settings.get("rate") or rate or 1))
        limit = buffer or max(1, int(hz))
        self._drop(key)
        queue = self._queues[key] = _Queue(limit, sensor_type(name))
        self._hz[key] = hz
        self._subscribed[key] = sensor_type(name)
        self._subs[key] = self._declare(sensor, key, queue, HISTORY_SHARE * limit / hz)

    def _declare(self, sensor: str, key: str, queue: _Queue, history_s: float) -> Any:
        ext = import_zenoh().ext
        history = (
            ext.HistoryConfig(
                detect_late_publishers=True, max_samples=HISTORY_BATCHES, max_age=history_s
            )
            if self.history
            else None
        )
        sub = ext.declare_advanced_subscriber(
            self.zsession,
            topic_key(self.name, sensor),
            lambda sample: self._received(queue, sensor, sample.payload.to_bytes()),
            history=history,
            recovery=ext.RecoveryConfig(heartbeat=True, periodic_queries=None),
        )
        missed = self.missed

        def on_miss(miss: Any) -> None:
            missed[key] = missed.get(key, 0) + int(miss.nb)

        sub.sample_miss_listener(on_miss)
        return sub

    def _drop(self, key: str) -> None:
        sub = self._subs.pop(key, None)
        if sub is not None:
            sub.undeclare()
        self._queues.pop(key, None)
        self._next.pop(key, None)
        self._stamp.pop(key, None)

    def unsubscribe(self, name: str) -> None:
        """Stop receiving ``name`` (the hub goes on publishing it for others)."""
        key = name.lower()
        self._drop(key)
        self._subscribed.pop(key, None)

    def read(self, name: str) -> Reading:
        """Every sample of ``name`` received since the last read, as :meth:`Hub.read`."""
        key = name.lower()
        queue = self._queues.get(key)
        if queue is None:
            raise DeviceError(f"not subscribed to {name}")
        kind = self._subscribed[key]
        batches, lost = self._in_order(key, queue.take())
        with queue.lock:
            lost += queue.overflow
            queue.overflow = 0
            if queue.errors:
                self.rejected[key] = self.rejected.get(key, 0) + queue.errors
                queue.errors = 0
        body = _join(kind, batches)
        n = sum(b.count for b in batches)
        stamp = batches[-1].stamp if batches else 0.0
        frame = HEADER.pack(int(kind), 0, 0, n, len(body), len(body), 0, stamp) + body
        reading = decode_reading(frame, key, None)
        if not self.hub_clock:
            reading.t = self.sync.client_times(key, reading.hub_t)
        reading.lost = lost
        if lost:
            self._lost[key] = self._lost.get(key, 0) + lost
        return reading

    def _in_order(self, key: str, batches: list[Batch]) -> tuple[list[Batch], int]:
        """The batches not seen before, in the order they were put, and the samples missing
        between them. A batch numbered before the next one expected is a duplicate, unless
        it was put after every batch taken: a restarted hub numbering from 0 again."""
        out, lost = [], 0
        expected, last = self._next.get(key), self._stamp.get(key, -math.inf)
        queue, hz = self._queues[key], self._hz.get(key, 1.0)
        for b in sorted(batches, key=lambda b: (b.stamp, b.first)):
            if expected is not None and b.first > expected + (
                GAP_MARGIN * hz * max(0.0, b.stamp - last) + queue.limit
            ):
                self.rejected[key] = self.rejected.get(key, 0) + 1
                continue  # more samples missing than the hub acquired meanwhile
            if expected is not None and b.first < expected:
                if not b.stamp > last:
                    self.duplicates[key] = self.duplicates.get(key, 0) + 1
                    continue
                expected = None  # a new numbering: nothing lost between the two
            if expected is not None:
                lost += b.first - expected
            expected, last = b.end, b.stamp
            out.append(b)
        if expected is not None:
            self._next[key], self._stamp[key] = expected, last
        return out, lost

    # ------------------------------------------------------------------ not over Zenoh

    def pull(self, name: str) -> bytes:
        raise DeviceError("pull: raw ros4mat frames are not sent over Zenoh; use read()")

    def serial(self, port: str, data: bytes = b"", **_: Any) -> bytes:
        raise DeviceError("the hub's serial ports are not served over Zenoh")

    def digital_out(self, d0: int, d1: int, d2: int, d3: int) -> None:
        raise DeviceError("the hub's digital outputs are not served over Zenoh")

    @property
    def url(self) -> str:
        return f"zenoh/{self.name}"

    @property
    def stats(self) -> LinkStats:
        """Batches received, by sensor (``stats.as_dict()``)."""
        return self._stats

    def close(self, stop: bool | None = None, *, quit: bool | None = None) -> None:
        """Undeclare every subscription and close the Zenoh session (``stop``: nothing more
        to stop over Zenoh; ``quit`` is its deprecated old name). Idempotent."""
        renamed_argument("ZenohHub.close", "quit", "stop", quit, stop, True)
        if self._closed:
            return
        self._closed = True
        for key in list(self._subs):
            self._drop(key)
        self._alive_sub.undeclare()  # type: ignore[no-untyped-call]
        close_session(self.zsession)

    def add_listener(self, listener: FrameListener, *, kind: str = "frames") -> ListenerHandle:
        """Call ``listener("rx", batch, t)`` with every batch received (the Zenoh payload,
        :mod:`robocli.zenoh.batch`); returns a handle whose ``remove()`` takes it off."""
        return self._add_listener(listener, kind)

    def _listeners_of(self, kind: str) -> Listeners[Any]:
        pick_kind(kind, ("frames",), "ZenohHub")
        return self._frames

    def __repr__(self) -> str:
        return f"<ZenohHub {self.name}>"


ZENOH_HUB.append(ZenohHub.connect)


def _join(kind: MsgType, batches: list[Batch]) -> bytes:
    """The bodies of ``batches`` as one ros4mat body: records end to end; for images and
    scans, every info record first, then every frame's bytes."""
    if kind not in BLOBS:
        return b"".join(b.body for b in batches)
    size = head_size(kind)
    heads = [b.body[: b.count * size] for b in batches]
    tails = [b.body[b.count * size :] for b in batches]
    return b"".join(heads) + b"".join(tails)
