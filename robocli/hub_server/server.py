""":class:`HubServer`: the hub's sources and rings served over ros4mat v3 TCP."""

from __future__ import annotations

import ctypes
import logging
import sys
from typing import Any

from robocli.errors import InvalidArgument
from robocli.hub_server.frontends.ros4mat import PullTimes, Ros4matSession
from robocli.hub_server.places import BUSY_REASON, Places
from robocli.hub_server.registry import ClientInfo, SensorRegistry
from robocli.hub_server.rings import DEFAULT_BUDGET
from robocli.hub_server.sources import SerialPorts, Source, hub_sources
from robocli.protocols.ros4mat import HEADER_SIZE, PORT
from robocli.serving.links import Link, ServerLinkStats
from robocli.serving.server import REAP_WAIT_S, Server
from robocli.serving.ticker import Ticker

__all__ = ["HUB_SWITCH_INTERVAL_S", "HubServer", "PORT", "tune_hub_process"]

log = logging.getLogger("robocli.hub_server")

MAX_BODY = 64 * 1024  #: largest request body accepted (bytes)
DETACHED_TTL_S = 600.0  #: a client gone without QUIT keeps its buffers this long
SEND_TIMEOUT_S = 10.0  #: a client may leave a reply unread this long (ros4mat's send timeout)
CONNECT_TIMEOUT_S = 2.0
"""A connection that has not sent a complete CONNECT this long after it opened is closed (the
original client sends it at once)."""
MAX_PENDING = 64  #: connections at once that have not completed CONNECT yet
MAX_PENDING_PER_ADDRESS = 32  #: the same, from one address
MAX_BACKLOG = 1 << 20
"""Bytes a connection may leave unread beyond the one reply it waits on (a connection handles
no request while a reply waits: a client that asks without reading holds one reply)."""
REFUSE_HEADROOM = 8
"""Connections beyond the clients and pending ones: the serving layer's plain-text refusal
line comes only beyond these (a full hub answers CONNECT with a ros4mat error reply)."""
EXPOSED_BINDS = ("0.0.0.0", "::", "")
IDLE_TIMEOUT_S = 60.0
"""With a token: a client without it that sends no request this long is closed."""
HUB_SWITCH_INTERVAL_S = 1e-4
"""The interpreter's thread switch interval for a process that is mainly a hub."""
MMAP_THRESHOLD = 256 << 10
"""Allocations from this size get their own pages, given back when freed (glibc)."""
_M_MMAP_THRESHOLD = -3  # glibc's mallopt parameter


def tune_hub_process() -> None:
    """Tune this interpreter for serving many clients: a thread waiting for the GIL gets it
    after :data:`HUB_SWITCH_INTERVAL_S` instead of 5 ms. A connection's thread hands the GIL
    over several times per pull (socket, C ring, copies); with 40 multi-threaded clients at
    the throughput target, p99 pull was 40-90 ms at 5 ms and 24-27 ms at 0.1 ms (measured
    before the self-locking ring, with 2 client processes).

    With glibc, a reply's buffers from :data:`MMAP_THRESHOLD` up are mapped on their own
    and unmapped when freed: glibc raises that threshold to the largest block freed (up to
    32 MiB), after which camera replies came from heaps that kept their peak. 50 clients
    pulling a 640x480 raw camera and never reading, for 20 s: peak RSS 534 MB without it,
    333 MB with it (60 reconnecting: 428 and 272 MB; the output budget is 129 MiB).
    Process-wide: ``robocli serve`` calls it; a library user decides."""
    sys.setswitchinterval(HUB_SWITCH_INTERVAL_S)
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # not glibc (macOS, Windows): nothing to set
        return
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    if not mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD):
        log.debug("mallopt(M_MMAP_THRESHOLD) refused")


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
    ``max_pending``/``max_per_address``: connections at once that have not completed CONNECT,
    in all and from one address; one more closes the oldest of them that sent nothing (else
    the oldest). They never take the places of clients: ``max_clients`` counts connections
    that completed CONNECT; one more gets a ros4mat error reply "hub full".
    ``reserved``: with a token, places only clients that presented it may take (default: a
    quarter of ``max_clients``, at least 1); clients without it hold the others, at most
    ``max_per_address`` from one address, and lose their place when idle ``idle_timeout`` s
    or when a client with the token finds the hub full (the one idle longest goes;
    :mod:`robocli.hub_server.places`).
    ``output_budget``: bytes of memory the replies waiting for their clients may hold over
    all connections (default: two full rings and 1 MiB); room is made by dropping the
    connections whose output waited longest, those without the token first, never a client
    with the token for one without (:class:`~robocli.serving.links.OutputBudget`).
    ``sources``: extra or replacement sources by sensor name.

    A connection whose stream loses its framing (garbage, a request body over ``max_body``,
    a request left half-sent for 1 s) is closed; a connected client's oversize request gets
    an error reply first.
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
        max_pending: int = MAX_PENDING,
        max_per_address: int = MAX_PENDING_PER_ADDRESS,
        reserved: int | None = None,
        idle_timeout: float = IDLE_TIMEOUT_S,
        output_budget: int | None = None,
        sources: dict[str, Source] | None = None,
    ) -> None:
        if max_clients < 1:
            raise InvalidArgument("max_clients must be >= 1")
        if max_body < 64:
            raise InvalidArgument("max_body must be >= 64 bytes")
        if not connect_timeout > 0:
            raise InvalidArgument("connect_timeout must be > 0 s")
        if max_pending < 1 or max_per_address < 1:
            raise InvalidArgument("max_pending and max_per_address must be >= 1")
        if reserved is None:
            reserved = max(1, max_clients // 4)
        if not 0 <= reserved <= max_clients or not idle_timeout > 0:
            raise InvalidArgument("reserved must be within 0..max_clients, idle_timeout > 0 s")
        if output_budget is None:
            output_budget = 2 * ring_budget + MAX_BACKLOG
        if output_budget < 1:
            raise InvalidArgument("output_budget must be >= 1 byte")
        self.connect_timeout = connect_timeout
        self.max_clients = max_clients
        self.bind, self._port = bind, port
        self.serial_ports = tuple(serial_ports)
        self.gpsd, self.pioneer = gpsd, pioneer
        if isinstance(token, str):
            token = token.encode()
        if token is not None and not token:
            raise InvalidArgument("token must not be empty")
        self._token = token
        self.places = Places(
            max_clients, token=token is not None, reserved=reserved,
            max_per_address=max_per_address, idle_timeout=idle_timeout,
        )  # fmt: skip
        """Who holds the client places (connections that completed CONNECT)."""
        self._max_body = max_body
        all_sources = hub_sources(sim, gpsd, pioneer)
        all_sources.update(sources or {})
        self.hub = SensorRegistry(all_sources, ring_budget=ring_budget,
                                  detached_ttl=detached_ttl,
                                  random_ids=token is not None)  # fmt: skip
        period = min(5.0, detached_ttl / 2, idle_timeout / 2)
        self._expiry = Ticker(period, self._expire, "hub-expiry")
        self.serial = SerialPorts(self.serial_ports) if self.serial_ports else None
        """The serial ports SERIAL_CMD may use (None: no ``serial_ports``)."""
        self._server = Server(
            self._session,
            protocol="ros4mat",
            max_clients=max_clients + max_pending + REFUSE_HEADROOM,
            max_frame=HEADER_SIZE + max_body,
            byte_timeout=1.0,
            send_timeout=send_timeout,
            max_backlog=MAX_BACKLOG,
            name="hub",
            busy_reason=BUSY_REASON,
            pace=True,
            output_budget=output_budget,
            strict_framing=True,
            handshake_timeout=connect_timeout,
            max_pending=max_pending,
            max_pending_per_address=max_per_address,
        )
        self._url: str | None = None
        self.warnings: list[str] = []
        self.pull_times = PullTimes()
        """Server-side pull durations (request framed -> reply built): percentiles."""

    def _expire(self, _now: float) -> None:
        self.hub.expire()
        self.places.expire()

    def _session(self, link: Link) -> Ros4matSession:
        return Ros4matSession(
            link, self.hub, link.name, self._token, self.serial, self.pull_times,
            admit=self._admit_client, on_end=self._session_ended, reap=self._server.reap,
            max_body=self._max_body,
        )  # fmt: skip

    def _admit_client(self, session: Ros4matSession) -> str | None:
        """A client place for a connection completing CONNECT: None, or why not. When the
        hub is full, the connections whose client has already closed are waited for first
        (at most :data:`~robocli.serving.server.REAP_WAIT_S`): the original client's ``close``
        then ``connect`` must not find its own old connection holding the last place."""
        if self.places.take(session) is None:
            return None
        self._server.reap(REAP_WAIT_S)
        refused = self.places.take(session)
        if refused is not None:
            log.warning("%s: client refused: %s", session.peer, refused)
        return refused

    def _session_ended(self, session: Ros4matSession) -> None:
        self.places.give_back(session)

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
    def started(self) -> bool:
        """Whether :meth:`start` made it listen on TCP."""
        return self._url is not None

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
    def output_peak(self) -> int:
        """The most bytes of memory the replies waiting for their clients ever held at once,
        over all connections (bounded by ``output_budget``)."""
        return self._server.budget.peak

    @property
    def evicted(self) -> int:
        """Connections closed before CONNECT to make room for newer ones."""
        return self._server.evicted

    @property
    def link_stats(self) -> ServerLinkStats:
        """Byte and frame counters summed over every connection, past and present."""
        return self._server.stats()

    def close(self) -> None:
        """Close every connection, stop every sensor (bounded). Idempotent."""
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
