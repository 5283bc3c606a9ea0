"""The hub's core, wire-agnostic: sensors (source + one ring + a driver) and clients (cursors).

Front-ends (the ros4mat TCP server, later others) call :class:`SensorRegistry` only: connect a
client, subscribe it to a sensor with parameters or silently, pull its new samples, unsubscribe,
quit. A sensor runs while at least one client (connected or detached) is subscribed; its driver
polls the source at the source's batch rate and pushes into the sensor's ring. Settings are shared:
a non-silent subscribe reconfigures the sensor for everyone (last writer wins), as in ros4mat. A
client that disconnects without QUIT is kept, detached, so that it can re-attach with its id and
find its buffers; at most ``max_detached`` are kept (the oldest go first), each for at most
``detached_ttl`` seconds (:meth:`SensorRegistry.expire`). Client ids are sequential, as ros4mat's,
or random (``random_ids``: a hub with a token, where an id must not be guessable).
"""

from __future__ import annotations

import copy
import itertools
import logging
import secrets
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from robocli.errors import DeviceError, InvalidArgument, RobocliError
from robocli.hub_server.rings import Cursor, SensorRing, ring_capacity
from robocli.hub_server.sources.base import Source
from robocli.serving.ticker import Ticker

__all__ = ["Channel", "ClientInfo", "ClientState", "Pulled", "SensorRegistry", "hub_clock"]

log = logging.getLogger("robocli.hub_server")

RING_SECONDS = 10.0  #: a ring holds this many seconds of samples (within its byte budget)


def hub_clock() -> Callable[[], float]:
    """The hub's clock: Unix time (s) advancing with the monotonic clock (no steps)."""
    wall0, mono0 = time.time(), time.monotonic()
    return lambda: wall0 + (time.monotonic() - mono0)


@dataclass(frozen=True)
class Pulled:
    """A pull's result: acquisition times, structured records, the source that made them."""

    t: npt.NDArray[np.float64]
    records: npt.NDArray[Any]
    source: Source


@dataclass(frozen=True)
class ClientInfo:
    """What :attr:`robocli.hub_server.HubServer.clients` shows of one client."""

    id: int
    peer: str
    connected: bool
    compress: bool
    subscriptions: dict[str, int]  #: sensor -> its buffer capacity (records)
    pulls: int
    samples: int
    dropped: int  #: samples dropped for it because it pulled too rarely


@dataclass
class ClientState:
    """One client's state, kept across reconnects until QUIT."""

    id: int
    peer: str = ""
    compress: bool = False
    authorized: bool = False
    connected: bool = False
    cursors: dict[str, Cursor] = field(default_factory=dict)
    pulls: int = 0
    samples: int = 0
    detached_at: float = 0.0


def _validated(source: Source, params: Mapping[str, Any]) -> Source:
    """A shallow copy of ``source`` configured with ``params`` (its record layout checked
    too), ``source`` itself untouched; :class:`InvalidArgument` for whatever the source
    cannot take. A source's ``configure`` sets its rates before it reads its other keys,
    and a value JSON allows (a list, ``1e400``) can fail in ``int()`` with any exception:
    trying on a copy is what keeps a refused request from changing anything."""
    trial = copy.copy(source)
    trial.params = dict(source.params)
    try:
        trial.configure(params)
        trial.dtype()
    except InvalidArgument:
        raise
    except (TypeError, ValueError, ArithmeticError, KeyError) as exc:
        raise InvalidArgument(f"bad settings: {type(exc).__name__}: {exc}") from None
    return trial


class Channel:
    """One sensor: its source, its ring (while subscribed) and its driver thread."""

    def __init__(self, source: Source, clock: Callable[[], float], budget: int) -> None:
        self.source = source
        self.name = source.name
        source.clock = clock
        self._clock = clock
        self._budget = budget
        self.ring: SensorRing | None = None
        self._ticker: Ticker | None = None
        self.lock = threading.Lock()
        self.poll_errors = 0  #: polls a real source failed (robot or daemon away)

    @property
    def active(self) -> bool:
        return self.ring is not None and self.ring.cursors > 0

    def configure(self, params: Mapping[str, Any] | None, buffer: int) -> bool:
        """Apply ``params`` (None: keep the current settings) with a ring of at least
        ``buffer`` records (within the byte budget). Returns whether the driver must
        (re)start: call :meth:`restart` once the new subscriber's cursor is attached."""
        src = self.source
        old_dtype = src.dtype()
        old = (dict(src.params), src.rate, src.batch_rate)
        if params is not None:
            trial = _validated(src, params)  # refused: nothing has changed
            src.params, src.rate, src.batch_rate = trial.params, trial.rate, trial.batch_rate
        changed = old != (dict(src.params), src.rate, src.batch_rate)
        dtype = src.dtype()
        wanted = max(buffer, int(src.rate * RING_SECONDS))
        capacity = ring_capacity(dtype.itemsize, wanted, self._budget)
        if self.ring is None:
            self.ring = SensorRing(self.name, dtype, capacity)
        elif dtype != old_dtype or (changed and capacity > self.ring.capacity):
            # new layout or faster rate: everyone's unread samples of the old settings go
            # (counted lost); a larger buffer alone is clamped instead, disturbing no one
            self.ring.reshape(dtype, capacity)
        return changed or self._ticker is None

    def restart(self) -> None:
        """(Re)start the driver with the source's current settings."""
        self._stop_driver()
        src = self.source
        src.start(self._clock())
        ticker = Ticker(1.0 / src.batch_rate, self._tick, f"hub-{self.name}")
        self._ticker = ticker
        ticker.start()

    def _tick(self, _now: float) -> None:
        try:
            t, records = self.source.poll(self._clock())
        except RobocliError as exc:  # a real source failing (robot gone): keep trying, quietly
            self.poll_errors += 1
            if self.poll_errors % 100 == 1:
                log.warning("%s: %s (%d poll errors)", self.name, exc, self.poll_errors)
            return
        ring = self.ring
        if len(t) and ring is not None and records.dtype == ring.dtype:
            ring.push(t, records)

    def _stop_driver(self) -> None:
        if self._ticker is not None:
            self._ticker.close()
            self._ticker = None
            self.source.stop()

    def stop(self) -> None:
        """Stop the driver and free the ring."""
        self._stop_driver()
        self.ring = None

    @property
    def errors(self) -> int:
        """Failed polls: source errors plus unexpected exceptions (logged by the ticker)."""
        return self.poll_errors + (self._ticker.errors if self._ticker is not None else 0)


class SensorRegistry:
    """Sensors and clients. Thread-safe; every front-end thread calls in."""

    def __init__(
        self,
        sources: Mapping[str, Source],
        *,
        clock: Callable[[], float] | None = None,
        max_detached: int = 256,
        detached_ttl: float = 600.0,
        ring_budget: int = 64 << 20,
        random_ids: bool = False,
    ) -> None:
        self.clock = clock or hub_clock()
        self.channels = {name: Channel(s, self.clock, ring_budget) for name, s in sources.items()}
        self.max_detached = max_detached
        self.detached_ttl = detached_ttl
        self._clients: dict[int, ClientState] = {}
        self._ids = itertools.count(1)
        self._random_ids = random_ids
        self._lock = threading.Lock()

    # ------------------------------------------------------------------ clients

    def connect(
        self, client_id: int, peer: str, compress: bool, *, resume: bool = True
    ) -> ClientState:
        """Attach a connection: the detached client ``client_id`` if ``resume``, else a new
        client. A connected client is never taken over: asking for its id gives a new one
        (the caller adopts the id it is given, as the original ros4mat client does). The
        client starts unauthorized."""
        with self._lock:
            state = self._clients.get(client_id) if client_id and resume else None
            if state is None or state.connected:
                state = ClientState(self._new_id())
                self._clients[state.id] = state
            state.peer, state.compress, state.connected = peer, compress, True
            state.authorized = False
            log.info("client %d connected from %s", state.id, peer)
            return state

    def _new_id(self) -> int:
        """An id no client has (lock held): the next in sequence, or a random 31-bit one."""
        while True:
            cid = secrets.randbelow(0x7FFFFFFF) + 1 if self._random_ids else next(self._ids)
            if cid not in self._clients:
                return cid

    def in_use(self, client_id: int) -> bool:
        """Whether a connection holds the client ``client_id`` now."""
        with self._lock:
            state = self._clients.get(client_id)
            return state is not None and state.connected

    def detached(self, client_id: int) -> bool:
        """Whether ``client_id`` is a known client with no connection."""
        with self._lock:
            state = self._clients.get(client_id)
            return state is not None and not state.connected

    def attach(self, client_id: int, peer: str) -> ClientState | None:
        """Re-attach a detached client by id without CONNECT (None: unknown or in use). It
        is unauthorized: no token came with this request."""
        with self._lock:
            state = self._clients.get(client_id)
            if state is None or state.connected:
                return None
            state.peer, state.connected, state.authorized = peer, True, False
            return state

    def detach(self, state: ClientState) -> None:
        """The connection ended without QUIT: keep the client and its buffers."""
        with self._lock:
            if self._clients.get(state.id) is not state:
                return
            state.connected = False
            state.detached_at = self.clock()
            detached = sorted(
                (c for c in self._clients.values() if not c.connected),
                key=lambda c: c.detached_at,
            )
            evict = detached[: max(0, len(detached) - self.max_detached)]
        for old in evict:
            self.quit(old)

    def expire(self) -> int:
        """Forget the clients detached for more than ``detached_ttl`` seconds (their sensors
        stop when nobody else uses them); returns how many."""
        limit = self.clock() - self.detached_ttl
        with self._lock:
            old = [c for c in self._clients.values() if not c.connected and c.detached_at < limit]
        for state in old:
            log.info("client %d forgotten: detached for %.0f s", state.id, self.detached_ttl)
            self.quit(state)
        return len(old)

    def quit(self, state: ClientState) -> None:
        """Forget the client: unsubscribe everything."""
        for name in list(state.cursors):
            self.unsubscribe(state, name)
        with self._lock:
            if self._clients.get(state.id) is state:
                del self._clients[state.id]
        state.connected = False

    # ------------------------------------------------------------------ sensors

    def channel(self, name: str) -> Channel:
        try:
            return self.channels[name]
        except KeyError:
            raise DeviceError(f"sensor {name!r} is not served by this hub") from None

    def subscribe(
        self, state: ClientState, name: str, params: Mapping[str, Any] | None, buffer: int
    ) -> int:
        """Subscribe ``state`` to sensor ``name``; returns its buffer capacity (records).

        ``params`` None is a silent subscribe: join the current settings (and copy another
        subscriber's capacity when ``buffer`` is 0); it fails if nobody is subscribed.
        ``buffer`` 0 means one second of samples. Raises :class:`DeviceError`.
        """
        ch = self.channel(name)
        with ch.lock:
            if params is None and not ch.active and name not in state.cursors:
                raise DeviceError(f"silent subscribe to {name}: nobody is subscribed to it")
            if params is None and not buffer:
                buffer = max((c.limit for c in self._cursors_of(name)), default=1)
            try:
                restart = ch.configure(params, buffer)
            except InvalidArgument as exc:
                raise DeviceError(f"{name}: {exc}") from exc
            ring = ch.ring
            assert ring is not None
            buffer = buffer or max(1, int(ch.source.rate))
            cursor = state.cursors.get(name)
            if cursor is None:
                state.cursors[name] = cursor = ring.attach(buffer)
            else:
                ring.set_limit(cursor, buffer)
            if restart:  # after the cursor exists: it sees the very first samples
                try:
                    ch.restart()
                except RobocliError as exc:  # the source could not start (a robot away)
                    ring.detach(cursor)
                    del state.cursors[name]
                    if ring.cursors == 0:
                        ch.stop()
                    raise DeviceError(f"{name}: {exc}") from exc
            how = "silent" if params is None else ch.source.settings()
            log.info(
                "client %d subscribed to %s (%s, buffer %d)", state.id, name, how, cursor.limit
            )
            return cursor.limit

    def _cursors_of(self, name: str) -> list[Cursor]:
        with self._lock:
            return [c.cursors[name] for c in self._clients.values() if name in c.cursors]

    def unsubscribe(self, state: ClientState, name: str) -> None:
        """Drop ``state``'s subscription (no error if it had none); the sensor stops when
        nobody is subscribed any more."""
        ch = self.channels.get(name)
        cursor = state.cursors.pop(name, None)
        if ch is None or cursor is None:
            return
        with ch.lock:
            if ch.ring is not None:
                ch.ring.detach(cursor)
                if ch.ring.cursors == 0:
                    ch.stop()
                    log.info("%s stopped: no subscriber left", name)

    def pull(self, state: ClientState, name: str) -> Pulled:
        """Every new sample of ``name`` for ``state`` (consumed for it only)."""
        cursor = state.cursors.get(name)
        ch = self.channels.get(name)
        ring = ch.ring if ch is not None else None
        if cursor is None or ring is None or ch is None:
            raise DeviceError(f"not subscribed to {name}")
        t, records = ring.read(cursor)
        state.pulls += 1
        state.samples += len(t)
        return Pulled(t, records, ch.source)

    def pull_size(self, state: ClientState, name: str) -> int:
        """Bytes a :meth:`pull` of ``name`` for ``state`` would copy now (records and
        times; more may come before the pull)."""
        ch, cursor = self.channels.get(name), state.cursors.get(name)
        ring = ch.ring if ch is not None else None
        if ring is None or cursor is None:
            return 0
        return ring.available(cursor) * (ring.dtype.itemsize + 8)

    def dropped(self, state: ClientState, name: str) -> int:
        """Samples of ``name`` dropped for ``state`` (it fell more than its buffer behind)."""
        ch, cursor = self.channels.get(name), state.cursors.get(name)
        if ch is None or cursor is None or ch.ring is None:
            return 0
        return ch.ring.lost(cursor)

    def dropped_seen(self) -> int:
        """Samples dropped for the known clients before samples they received: the gaps
        they can see (:meth:`SensorRing.lost_seen`), where :meth:`dropped` also counts those
        a client's next pull will show."""
        with self._lock:
            states = list(self._clients.values())
        return sum(ch.ring.lost_seen(c) for s in states for n, c in list(s.cursors.items())
                   if (ch := self.channels.get(n)) is not None and ch.ring is not None)  # fmt: skip

    def digital_out(self, levels: list[int]) -> None:
        """Set the ADC board's four digital outputs (kept by the ADC source, shown in
        :meth:`sensors`)."""
        ch = self.channel("adc")
        if not hasattr(ch.source, "digital"):
            raise DeviceError("this hub's ADC has no digital outputs")
        if len(levels) != 4:
            raise InvalidArgument("digital_out takes exactly 4 levels")
        ch.source.digital = [1 if v else 0 for v in levels]

    # ------------------------------------------------------------------ views

    def clients(self) -> list[ClientInfo]:
        with self._lock:
            states = list(self._clients.values())
        return [
            ClientInfo(
                s.id,
                s.peer,
                s.connected,
                s.compress,
                {n: c.limit for n, c in s.cursors.items()},
                s.pulls,
                s.samples,
                sum(self.dropped(s, n) for n in list(s.cursors)),
            )
            for s in states
        ]

    def sensors(self) -> dict[str, dict[str, Any]]:
        out = {}
        for name, ch in self.channels.items():
            ring = ch.ring
            out[name] = {
                "active": ch.active,
                "simulated": ch.source.simulated,
                "subscribers": ring.cursors if ring is not None else 0,
                "ring_records": ring.capacity if ring is not None else 0,
                "ring_bytes": ring.nbytes if ring is not None else 0,
                "errors": ch.errors,
                **ch.source.settings(),
            }
        return out

    def close(self) -> None:
        """Stop every driver and forget every client."""
        for ch in self.channels.values():
            with ch.lock:
                ch.stop()
        with self._lock:
            self._clients.clear()
