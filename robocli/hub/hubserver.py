""":class:`HubServer`: the hub's sources and rings served over ros4mat v3 TCP."""

from __future__ import annotations

import logging
import sys
import threading
from typing import Any

from robocli.errors import InvalidArgument
from robocli.hub.registry import ClientInfo, Hub
from robocli.hub.rings import DEFAULT_BUDGET
from robocli.hub.server import PullTimes, Ros4matSession
from robocli.hub.sources import SerialPorts, Source, hub_sources
from robocli.protocols.ros4mat import HEADER_SIZE, PORT
from robocli.sim.links import Link, LinkStats
from robocli.sim.serving import Server, Ticker

__all__ = ["HUB_SWITCH_INTERVAL_S", "HubServer", "PORT", "tune_hub_process"]

log = logging.getLogger("robocli.hub")

MAX_BODY = 64 * 1024  #: largest request body accepted (bytes)
DETACHED_TTL_S = 600.0  #: a client gone without QUIT keeps its buffers this long
SEND_TIMEOUT_S = 10.0  #: a client may leave a reply unread this long (ros4mat's send timeout)
CONNECT_TIMEOUT_S = 10.0
"""A connection that has not sent a complete CONNECT this long after it opened is closed:
idle or half-sent connections must not hold the ``max_clients`` slots."""
REFUSE_HEADROOM = 8
"""Connections beyond ``max_clients`` answered with a ros4mat error reply ("hub full") rather
than the serving layer's plain-text refusal line, which a ros4mat client cannot parse."""
WATCH_PERIOD_S = 0.25  #: how often the connections are checked (handshake, oversize requests)
EXPOSED_BINDS = ("0.0.0.0", "::", "")
BUSY_REASON = "hub full: too many clients"
HUB_SWITCH_INTERVAL_S = 1e-4
"""The interpreter's thread switch interval for a process that is mainly a hub."""


def tune_hub_process() -> None:
    """Tune this interpreter for serving many clients: a thread waiting for the GIL gets it
    after :data:`HUB_SWITCH_INTERVAL_S` instead of 5 ms. A connection's thread hands the GIL
    over several times per pull (socket, C ring, copies); with 40 multi-threaded clients at
    the throughput target, p99 pull was 40-90 ms at 5 ms and 24-27 ms at 0.1 ms (measured
    before the self-locking ring, with 2 client processes).
    Process-wide: ``robocli serve`` calls it; a library user decides."""
    sys.setswitchinterval(HUB_SWITCH_INTERVAL_S)


class HubServer:
    """The sensor hub: sensor sources, one ring per sensor, the ros4mat front-end.

    ``bind``/``port``: where to listen (port 0: ephemeral; ros4mat's is 1500). ``sim``: serve
    the simulated sensors. ``serial_ports``: local serial ports a client may use through
    SERIAL_CMD (no other). ``gpsd``: ``"HOST:PORT"`` of a gpsd daemon for the GPS.
    ``pioneer``: URL of a Pioneer robot (or simulator) for the battery and ADC.
    ``token``: shared secret required for the commands that change settings or write to a
    serial port (None: open, as ros4mat).
    ``max_clients``: connections at once; ``max_body``: largest request body (bytes).
    ``ring_budget``: bytes one sensor's ring may hold (also bounds one reply).
    ``send_timeout``: seconds a client may leave a reply unread before it is dropped.
    ``detached_ttl``: seconds a client gone without QUIT keeps its subscriptions and buffers
    for a reconnect with its id.
    ``connect_timeout``: seconds a new connection has to send a complete CONNECT (or a
    request re-attaching a detached client id) before it is closed.
    ``sources``: extra or replacement sources by sensor name.

    A connection whose first request declares a body over ``max_body`` is closed within
    :data:`WATCH_PERIOD_S`.
    """

    def __init__(
        self,
        bind: str = "127.0.0.1",
        port: int = PORT,
        *,
        sim: bool = True,
        serial_ports: tuple[str, ...] | list[str] = (),
        gpsd: str | None = None,
        pioneer: str | None = None,
        token: str | bytes | None = None,
        max_clients: int = 64,
        max_body: int = MAX_BODY,
        ring_budget: int = DEFAULT_BUDGET,
        send_timeout: float = SEND_TIMEOUT_S,
        detached_ttl: float = DETACHED_TTL_S,
        connect_timeout: float = CONNECT_TIMEOUT_S,
        sources: dict[str, Source] | None = None,
    ) -> None:
        if max_clients < 1:
            raise InvalidArgument("max_clients must be >= 1")
        if max_body < 64:
            raise InvalidArgument("max_body must be >= 64 bytes")
        if not connect_timeout > 0:
            raise InvalidArgument("connect_timeout must be > 0 s")
        self.connect_timeout = connect_timeout
        self.max_clients = max_clients
        self._sessions = 0  # connections admitted as clients (at most max_clients)
        self._sessions_lock = threading.Lock()
        self.bind, self._port = bind, port
        self.serial_ports = tuple(serial_ports)
        self.gpsd, self.pioneer = gpsd, pioneer
        if isinstance(token, str):
            token = token.encode()
        if token is not None and not token:
            raise InvalidArgument("token must not be empty")
        self._token = token
        self._max_body = max_body
        all_sources = hub_sources(sim, gpsd, pioneer)
        all_sources.update(sources or {})
        self.hub = Hub(all_sources, ring_budget=ring_budget, detached_ttl=detached_ttl)
        self._expiry = Ticker(min(5.0, detached_ttl / 2), self._expire, "hub-expiry")
        self._watch = Ticker(min(WATCH_PERIOD_S, connect_timeout / 4), self._watch_links,
                             "hub-watch")  # fmt: skip
        self.serial = SerialPorts(self.serial_ports) if self.serial_ports else None
        """The serial ports SERIAL_CMD may use (None: no ``serial_ports``)."""
        self._server = Server(
            self._session,
            protocol="ros4mat",
            max_clients=max_clients + REFUSE_HEADROOM,
            max_frame=HEADER_SIZE + max_body,
            byte_timeout=1.0,
            send_timeout=send_timeout,
            max_backlog=ring_budget + (1 << 20),
            name="hub",
            busy_reason=BUSY_REASON,
        )
        self._url: str | None = None
        self.warnings: list[str] = []
        self.pull_times = PullTimes()
        """Server-side pull durations (request framed -> reply built): percentiles."""

    def _expire(self, _now: float) -> None:
        self.hub.expire()

    def _watch_links(self, now: float) -> None:
        """Close the connections without a client: those that sent no CONNECT within
        ``connect_timeout``, and those whose first request declared a body over
        ``max_body`` (not a ros4mat client: the framer dropped it, no reply can name it).
        A connected client's oversize request is skipped, as garbage is (the framer
        resynchronises)."""
        for link in self._server.links():
            session = link.session
            if not isinstance(session, Ros4matSession) or session.state is not None:
                continue
            if now - session.opened > self.connect_timeout:
                log.info("%s: no CONNECT within %g s; closing", link.name, self.connect_timeout)
                link.close()
            elif link.stats.oversize:
                log.info("%s: a request body over %d bytes before CONNECT; closing", link.name,
                         self._max_body)  # fmt: skip
                link.close()

    def _session(self, link: Link) -> Ros4matSession:
        with self._sessions_lock:
            full = self._sessions >= self.max_clients
            if not full:
                self._sessions += 1
        if full:  # answered in ros4mat: an error reply to each request, then closed
            log.warning("%s refused: %s", link.name, BUSY_REASON)
            return Ros4matSession(link, self.hub, link.name, None, None, refuse=BUSY_REASON)
        return Ros4matSession(link, self.hub, link.name, self._token, self.serial,
                              self.pull_times, on_end=self._session_ended)  # fmt: skip

    def _session_ended(self) -> None:
        with self._sessions_lock:
            self._sessions -= 1

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> HubServer:
        """Listen and serve; returns self. Binding every interface logs a loud warning (also
        kept in :attr:`warnings`)."""
        msg = self.exposure_warning()
        if msg is not None:
            self.warnings.append(msg)
            log.warning(msg)
        self._url = self._server.serve_tcp(self.bind, self._port)
        self._expiry.start()
        self._watch.start()
        return self

    def exposure_warning(self) -> str | None:
        """What a hub bound to every interface exposes, said loudly (None on a specific
        address)."""
        if self.bind not in EXPOSED_BINDS:
            return None
        what = ", ".join(sorted(self.hub.channels)) or "no sensor"
        extra = f"; serial ports {', '.join(self.serial_ports)}" if self.serial_ports else ""
        auth = "token required for settings and serial" if self._token else "NO authentication"
        return (f"hub listening on ALL interfaces ({self.bind or '*'}): anyone on the network "
                f"can read {what}{extra} ({auth})")  # fmt: skip

    @property
    def url(self) -> str:
        """``tcp://HOST:PORT`` (after :meth:`start`)."""
        if self._url is None:
            raise InvalidArgument("the hub is not started")
        return self._url

    @property
    def port(self) -> int:
        """The bound TCP port (after :meth:`start`)."""
        return int(self.url.rsplit(":", 1)[1])

    @property
    def clients(self) -> list[ClientInfo]:
        """Every known client: connected, or detached with its buffers kept."""
        return self.hub.clients()

    @property
    def sensors(self) -> dict[str, dict[str, Any]]:
        """Sensor name -> its settings, rate, ring and subscriber count."""
        return self.hub.sensors()

    @property
    def link_stats(self) -> LinkStats:
        """Byte and frame counters summed over every connection, past and present."""
        return self._server.stats()

    def close(self) -> None:
        """Close every connection, stop every sensor (bounded). Idempotent."""
        self._watch.close()
        self._server.close()
        self._expiry.close()
        self.hub.close()
        if self.serial is not None:
            self.serial.close()

    def __enter__(self) -> HubServer:
        if self._url is None:
            self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
