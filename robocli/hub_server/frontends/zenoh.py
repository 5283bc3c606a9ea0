"""The Zenoh front-end of the hub, beside the ros4mat TCP one, over the same sources and rings.

One Zenoh session (opened by the caller: ``robocli serve --zenoh``) publishes every sensor
that runs on ``robocli/<hub>/<sensor>`` (the key layout: :mod:`robocli.zenoh.keys`), one put
per batch every ``period`` seconds (the encoding: :mod:`robocli.zenoh.batch`). The
front-end is one client of :class:`~robocli.hub_server.registry.SensorRegistry`, with one cursor
per sensor it publishes, however many Zenoh subscribers there are: Zenoh copies to them, not
the hub.

* The sensors of ``publish`` start at once with their settings; any sensor a ros4mat client
  starts is published too, for as long as someone else keeps it running.
* Each sensor's publisher is a Zenoh *advanced publisher*: it keeps the last
  ``history_s`` seconds of batches for late joiners, and sends a heartbeat so that an
  advanced subscriber detects (and recovers from the cache) the batches it missed. The
  batches carry sample sequence numbers as well, for any other reader.
* ``robocli/<hub>/@info``: a queryable answering what the hub serves (JSON).
* ``robocli/<hub>/@settings/<sensor>``: a queryable changing a sensor's settings (and
  starting it), JSON ``{"params": {...}, "token": "..."}`` as the query's payload; refused
  without the token when the hub has one. Settings are shared, as over ros4mat: last
  writer wins.
* A liveliness token ``robocli/<hub>/@alive/hub`` while it runs.
* With ``serial`` (the hub's allow-list), its serial ports streamed to one user each
  (:mod:`robocli.hub_server.frontends.zenoh_serial`).

Zenoh's callbacks (queries) run on Zenoh's threads and never raise into them; the batches
go out from one ticker thread.
"""

from __future__ import annotations

import hmac
import json
import logging
import threading
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

from robocli.errors import DeviceError, ProtocolError, RobocliError
from robocli.hub_server.frontends.ros4mat import SENSOR_IDS, body_parts
from robocli.hub_server.frontends.zenoh_serial import ZenohSerial
from robocli.hub_server.registry import ClientState, SensorRegistry
from robocli.hub_server.sources import SerialPorts
from robocli.serving.ticker import Ticker
from robocli.zenoh.batch import SCHEMA, encode_head
from robocli.zenoh.keys import alive_key, check_name, info_key, settings_key, topic_key
from robocli.zenoh.payload import decode_object
from robocli.zenoh.session import import_zenoh

if TYPE_CHECKING:
    import zenoh

__all__ = ["BATCH_PERIOD_S", "HISTORY_S", "SENSOR_ID_OF", "ZenohFrontend", "sensor_encoding"]

log = logging.getLogger("robocli.hub_server")

BATCH_PERIOD_S = 0.025  #: one put per sensor at most this often (s)
HISTORY_S = 2.0  #: seconds of batches each publisher keeps for late joiners
HEARTBEAT_S = 0.5  #: the advanced publishers' heartbeat (miss detection of the last batch)
MAX_QUERY_BYTES = 64 * 1024  #: the largest settings query payload taken
SENSOR_ID_OF = {name: sensor_id for sensor_id, name in SENSOR_IDS.items()}
"""The hub's sensor name -> its ros4mat message id (the batch header's sensor field)."""


def sensor_encoding(sensor: str) -> str:
    """The Zenoh encoding of ``sensor``'s batches."""
    return f"application/octet-stream;{SCHEMA};sensor={sensor}"


class _Published:
    """One sensor on Zenoh: its advanced publisher and its sequence numbers."""

    def __init__(self, publisher: Any, sensor_id: int) -> None:
        self.publisher = publisher
        self.sensor_id = sensor_id
        self.next_seq = 0
        self.lost_seen = 0  # the cursor's lost count already folded into next_seq
        self.batches = 0
        self.samples = 0
        self.bytes = 0


class ZenohFrontend:
    """Publishes a :class:`SensorRegistry`'s sensors on a Zenoh ``session`` under ``name``.

    ``token``: the hub's token, required by the settings queryable (None: open).
    ``publish``: sensor -> settings (ros4mat SUBSCRIBE parameters; empty or None: its
    defaults) started at :meth:`start`. ``period``: seconds between two puts of a sensor.
    ``history_s``: seconds of batches kept for late joiners. ``serial``: the hub's serial
    ports, streamed (:class:`ZenohSerial`). ``on_batch``: see :attr:`on_batch` (``serve
    --ros2``: :class:`robocli.hub_server.frontends.ros2.HubTopics`). The session stays the
    caller's: :meth:`close` undeclares what this front-end declared.
    """

    def __init__(
        self,
        hub: SensorRegistry,
        session: zenoh.Session,
        name: str,
        *,
        token: bytes | None = None,
        publish: Mapping[str, Mapping[str, Any] | None] | None = None,
        period: float = BATCH_PERIOD_S,
        history_s: float = HISTORY_S,
        serial: SerialPorts | None = None,
        on_batch: Callable[[int, int, list[Any]], None] | None = None,
    ) -> None:
        self.hub, self.session = hub, session
        self._serial_ports = serial
        self.serial: ZenohSerial | None = None
        """The serial streams (with ``serial``, once started)."""
        self.name = check_name(name, "hub name")
        self._token = token
        for sensor in publish or {}:
            hub.channel(sensor)  # an unknown sensor: DeviceError now, not later
        self._publish = dict(publish or {})
        self.period = period
        self.history = max(1, round(history_s / period))  # batches kept per publisher
        self._state: ClientState | None = None
        self._published: dict[str, _Published] = {}
        self._joined: set[str] = set()  # started by someone else: published while they run
        self._lock = threading.Lock()
        self._ticker = Ticker(period, self._tick, f"hub-zenoh-{self.name}")
        self._declared: list[Any] = []
        self.refused = 0  #: settings queries refused
        #: called with (sensor id, samples, body parts) after each batch is put, on the
        #: ticker's thread: the parts are views of the ring's records, valid until it returns
        self.on_batch = on_batch

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> ZenohFrontend:
        """Start the sensors of ``publish``, declare the queryables and then the liveliness
        token, and start publishing. Returns self."""
        self._state = self.hub.connect(0, "zenoh", False, resume=False)
        for sensor, params in self._publish.items():
            self._subscribe(sensor, dict(params or {}))
        s = self.session
        self._declared.append(s.declare_queryable(info_key(self.name), self._on_info))
        self._declared.append(s.declare_queryable(settings_key(self.name), self._on_settings))
        if self._serial_ports is not None:
            self.serial = ZenohSerial(s, self.name, self._serial_ports, self._token)
        # the token last: a client that sees the hub come up finds every queryable declared
        # (a virtual serial line resuming asks serial-open the moment the token appears)
        self._declared.append(s.liveliness().declare_token(alive_key(self.name, "hub")))
        self._ticker.start()
        return self

    def close(self) -> None:
        """Stop publishing, undeclare everything, release the hub's sensors and serial ports.
        Idempotent."""
        self._ticker.close()
        if self.serial is not None:
            self.serial.close()
        with self._lock:
            for entity in [*self._declared, *(p.publisher for p in self._published.values())]:
                try:
                    entity.undeclare()
                except Exception as exc:
                    log.debug("zenoh undeclare: %s", exc)
            self._declared.clear()
            self._published.clear()
            if self._state is not None:
                self.hub.quit(self._state)
                self._state = None

    def __enter__(self) -> ZenohFrontend:
        return self.start() if self._state is None else self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ publishing

    def _publisher(self, sensor: str) -> _Published:
        pub = self._published.get(sensor)
        if pub is None:
            ext = import_zenoh().ext
            z = import_zenoh()
            publisher = ext.declare_advanced_publisher(
                self.session,
                topic_key(self.name, sensor),
                encoding=z.Encoding(sensor_encoding(sensor)),
                cache=ext.CacheConfig(self.history),
                sample_miss_detection=ext.MissDetectionConfig(
                    heartbeat=HEARTBEAT_S, sporadic_heartbeat=None
                ),
                publisher_detection=True,
            )
            pub = self._published[sensor] = _Published(publisher, SENSOR_ID_OF.get(sensor, 0))
        return pub

    def _subscribe(self, sensor: str, params: Mapping[str, Any] | None) -> None:
        """Configure ``sensor`` (None: join its settings) and publish it (lock held or at
        start). Its samples not yet put are put first: a new subscribe empties the cursor."""
        assert self._state is not None
        if sensor in self._state.cursors:
            self._put(sensor)
        self.hub.subscribe(self._state, sensor, params, 0)  # a buffer of 1 s of samples
        self._publisher(sensor)

    def _tick(self, _now: float) -> None:
        with self._lock:
            state = self._state
            if state is None:
                return
            for sensor, ch in self.hub.channels.items():
                running = ch.ring.cursors if ch.ring is not None else 0
                if sensor not in state.cursors and running:
                    try:  # a sensor someone else started: publish it while they keep it
                        self._subscribe(sensor, None)
                        self._joined.add(sensor)
                    except RobocliError as exc:
                        log.debug("zenoh: cannot join %s: %s", sensor, exc)
                elif sensor in self._joined and running <= 1:
                    self._put(sensor)
                    self.hub.unsubscribe(state, sensor)  # they left: let it stop
                    self._joined.discard(sensor)
            for sensor in list(state.cursors):
                self._put(sensor)

    def _put(self, sensor: str) -> None:
        """Put ``sensor``'s new samples as one batch (nothing when there are none)."""
        state = self._state
        assert state is not None
        pulled = self.hub.pull(state, sensor)
        pub = self._publisher(sensor)
        lost = self.hub.dropped(state, sensor)
        pub.next_seq += max(0, lost - pub.lost_seen)  # our own cursor overflowed: a gap
        pub.lost_seen = lost
        n = len(pulled.t)
        if not n:
            return
        parts = body_parts(pulled)
        size = sum(memoryview(p).nbytes for p in parts)
        head = encode_head(pub.sensor_id, pub.next_seq, n, size, self.hub.clock())
        pub.publisher.put(b"".join([head, *parts]))  # one copy out of the records
        if self.on_batch is not None:
            self.on_batch(pub.sensor_id, n, parts)
        pub.next_seq += n
        pub.batches += 1
        pub.samples += n
        pub.bytes += len(head) + size

    # ------------------------------------------------------------------ queryables

    def info(self) -> dict[str, Any]:
        """What ``robocli/<hub>/@info`` answers: the hub, its clock now, its sensors (each
        with its settings, whether it is published, its key and batch counters)."""
        sensors = {}
        with self._lock:  # a consistent view: the ticker adds publishers
            published = dict(self._published)
            cursors = set(self._state.cursors) if self._state is not None else set()
        for sensor, s in self.hub.sensors().items():
            pub = published.get(sensor)
            sensors[sensor] = {
                **s,
                "key": topic_key(self.name, sensor),
                "published": sensor in cursors,
                "encoding": sensor_encoding(sensor),
                "batches": pub.batches if pub else 0,
                "samples": pub.samples if pub else 0,
                "next_seq": pub.next_seq if pub else 0,
            }
        return {
            "name": self.name,
            "kind": "hub",
            "clock": self.hub.clock(),
            "batch_period_s": self.period,
            "history_batches": self.history,
            "token_required": self._token is not None,
            "sensors": sensors,
        }

    def _on_info(self, query: Any) -> None:
        try:
            query.reply(info_key(self.name), json.dumps(self.info(), default=_plain),
                        encoding=import_zenoh().Encoding.APPLICATION_JSON)  # fmt: skip
        except Exception as exc:
            log.warning("zenoh @info: %s", exc)

    def _on_settings(self, query: Any) -> None:
        """Every query gets a reply: the settings, or an error (a refusal, or what went
        wrong, logged whole: never raised into Zenoh's thread, never left unanswered)."""
        try:
            sensor = str(query.key_expr).rsplit("/", 1)[-1]
            try:
                answer = json.dumps(self.configure(sensor, _query_json(query)), default=_plain)
            except RobocliError as exc:
                self.refused += 1
                query.reply_err(json.dumps({"error": str(exc)}))
                return
            except Exception as exc:
                log.exception("zenoh @settings: %s failed", sensor)
                self.refused += 1
                query.reply_err(json.dumps({"error": f"{sensor}: internal error: {exc!r}"}))
                return
            query.reply(query.key_expr, answer,
                        encoding=import_zenoh().Encoding.APPLICATION_JSON)  # fmt: skip
        except Exception as exc:
            log.warning("zenoh @settings: no reply could be sent: %s", exc)

    def configure(self, sensor: str, request: Mapping[str, Any]) -> dict[str, Any]:
        """Apply a settings request (``{"params": {...}, "token": "..."}``) to ``sensor``
        and publish it; returns its settings. :class:`DeviceError` when refused."""
        if self._token is not None:
            given = request.get("token")
            if not isinstance(given, str) or not hmac.compare_digest(given.encode(), self._token):
                raise DeviceError(f"unauthorized: changing {sensor} needs the hub's token")
        params = request.get("params")
        if not isinstance(params, Mapping):
            raise DeviceError(f"{sensor}: 'params' must be an object of settings")
        with self._lock:
            if self._state is None:
                raise DeviceError("the hub is closing")
            try:
                self._subscribe(sensor, params)
            except (TypeError, ValueError) as exc:  # a JSON value a source cannot take
                raise DeviceError(f"{sensor}: {exc}") from None
            self._joined.discard(sensor)  # asked for over Zenoh: published from now on
            return self.hub.channel(sensor).source.settings()


def _query_json(query: Any) -> dict[str, Any]:
    payload = query.payload
    raw = payload.to_bytes() if payload is not None else b""
    try:
        return decode_object(raw or b"{}", "settings query", MAX_QUERY_BYTES)
    except ProtocolError as exc:  # refused as any other request: an error reply
        raise DeviceError(str(exc)) from None


def _plain(value: Any) -> Any:
    """JSON for NumPy scalars and anything else a source's settings may hold."""
    return value.item() if hasattr(value, "item") else str(value)
