"""Pioneer robots (P3-DX family) over ARCOS: serial port or TCP (MobileSim/robocli sim: 8101).

>>> with Pioneer.connect("tcp://127.0.0.1:8101") as robot:   # doctest: +SKIP
...     robot.enable_motors()
...     robot.set_velocity(0.2, 0.0)          # m/s, rad/s
...     x, y, th = robot.pose                 # m, m, rad (odometry)

The client does what the vendor SDK does to keep a robot safe and alive, on the shared
machinery of :mod:`robocli.devices.session`: a reader thread decodes every SIP; set-points
are re-sent at least every ``keepalive`` seconds and PULSE goes out when nothing else was
sent, so the robot's 2 s watchdog never trips while the program runs; an optional dead-man
stops the robot if the program stops commanding; leaving the ``with`` block, Ctrl-C, an
exception or a lost link stops the robot and CLOSEs. No SIP for ``sip_timeout`` seconds
raises :class:`robocli.errors.TimeoutError` to the caller. A listener that raises is
counted (``stats.listener_errors``) and never stops the keep-alive.

A program that stalls past the robot's watchdog while the robot was commanded to move
(stopped with SIGSTOP or Ctrl-Z, a debugger, a long GC pause, a suspended laptop) has had
its robot stopped by the watchdog. The client never resumes that motion: the first packet
after the stall is a stop in place of the stale set-points, which are cleared; the trip
goes to :meth:`Pioneer.on_watchdog_trip` listeners, and the program's next motion command
raises :class:`WatchdogTripped`. The robot moves again on the command after that.

Clocks: every ``t`` here is ``time.monotonic()`` at reception on this computer.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Iterable
from typing import Any, cast

from robocli.addresses import parse_device_url
from robocli.core import Framer
from robocli.devices import simulators
from robocli.devices.base import (
    ListenerHandle,
    SessionDevice,
    close_simulator,
    not_over_zenoh,
    pick_kind,
    renamed_argument,
)
from robocli.devices.pioneer import link
from robocli.devices.pioneer.commands import Commands, _finite
from robocli.devices.pioneer.decode import Decoding
from robocli.devices.pioneer.deprecated import DeprecatedNames
from robocli.devices.pioneer.keepalive import (
    DEFAULT_WATCHDOG_S,
    KeepAlive,
    WatchdogListener,
    WatchdogTrip,
    WatchdogTripped,
)
from robocli.devices.pioneer.link import PioneerStats
from robocli.devices.pioneer.simulated import PioneerSimulator, is_simulator
from robocli.devices.pioneer.state import Odometry, PioneerState, RobotIdentity
from robocli.devices.session import FrameListener, Listeners, Session
from robocli.errors import DeviceError, InvalidArgument, TimeoutError
from robocli.protocols import arcos
from robocli.protocols.arcos import Command
from robocli.robots.pioneer import RobotParams
from robocli.transports import Transport, open_transport

log = logging.getLogger("robocli.devices.pioneer")

#: Listener signature: (direction "tx"/"rx", payload = type byte + data, monotonic time).
PacketListener = FrameListener


class Pioneer(Commands, Decoding, DeprecatedNames, SessionDevice):
    """A connected Pioneer. Make one with :meth:`connect`; use it as a context manager.

    Here: connecting, the state, listeners and closing. Its commands come from
    :class:`~robocli.devices.pioneer.commands.Commands`; keeping it safe and alive (set-points,
    watchdog trips, dead-man) is a part it holds,
    :class:`~robocli.devices.pioneer.keepalive.KeepAlive`; the
    frames it receives are decoded by :class:`~robocli.devices.pioneer.decode.Decoding`.
    What only a simulator offers is a part of it, :attr:`sim` (None on a real robot): its
    laser (``robot.sim.start_laser()``, ``robot.sim.laser``), its status, teleporting."""

    def __init__(
        self,
        session: Session,
        *,
        identity: RobotIdentity,
        params: RobotParams,
        config: dict[str, Any] | None,
        sip_timeout: float = 8.0,
        keepalive: float = 0.4,
        deadman: float | None = None,
    ) -> None:
        """Use :meth:`connect` or :meth:`from_transport`: they run the handshake first."""
        self.transport: Transport = session.transport
        self.identity = identity
        self.params = params
        self.config = config
        self.sip_timeout = sip_timeout
        self.keepalive = keepalive
        self.deadman = deadman
        watchdog_ms = (config or {}).get("watchdog")
        #: the robot's watchdog (s): CONFIG's, else 2 s. A program that sends nothing for
        #: longer while the robot was commanded to move has stalled (:class:`WatchdogTrip`)
        self.watchdog: float = watchdog_ms / 1000.0 if watchdog_ms else DEFAULT_WATCHDOG_S
        self.io: dict[str, Any] | None = None  #: last IO packet (0xF0), raw fields
        self.encoders: tuple[int, int] | None = None  #: last encoder packet (0x90), ticks
        self.battery_info: dict[str, Any] | None = None
        self._session = session
        #: link and robot counters, thread-safe: ``stats.as_dict()`` for a consistent copy
        self.stats: PioneerStats = session.stats  # type: ignore[assignment]
        self._odo = Odometry()
        n_sonar = max(16, len(params.sonar))
        self._sonar = [math.nan] * n_sonar
        self._sonar_t = [math.nan] * n_sonar
        self._state: PioneerState | None = None  # built lazily from _sip
        self._sip: tuple[bytes, float, tuple[int, int]] | None = None  # body, t, odometry
        self._config_raw = b""
        now = time.monotonic()
        self._last_sip = now
        self._soc_seen = False  # a SIP reported a non-zero state of charge
        self._clamp_warned: set[str] = set()
        #: set-points kept alive, watchdog trips, dead-man, SIP supervision: a part
        self._keeper = KeepAlive(self)
        self._simulated = PioneerSimulator(self)
        session.on_frame = self._on_frame
        keeper = self._keeper
        session.on_sent = keeper.on_sent  # the time of every packet sent
        session.before_send = keeper.before_send
        session.silence_limit = self.watchdog  # a set-point held up past it is not sent
        session.add_task("keepalive", keeper.keepalive_step)
        keeper.supervisor = session.add_task("supervisor", keeper.supervise_step)
        session.start()

    # ------------------------------------------------------------------ connecting

    @classmethod
    def connect(
        cls,
        url: str,
        *,
        subtype: str | None = None,
        params: RobotParams | None = None,
        baudrate: int | None = None,
        switch_baud: int | None = None,
        timeout: float = 5.0,
        sip_timeout: float = 8.0,
        keepalive: float = 0.4,
        deadman: float | None = None,
        require_config: bool = False,
        listeners: Iterable[PacketListener] = (),
        laser: bool = False,
        baud: int | None = None,
        zenoh: str | None = None,
    ) -> Pioneer:
        """Open ``url`` (``/dev/ttyUSB0``, ``COM1``, ``tcp://host:8101``, pyserial URLs, or
        ``sim://[SUBTYPE][?OPTION=VALUE...]``: the built-in simulator, started in-process on
        loopback and closed with the robot; see ``docs/urls.md``), run the ARCOS handshake
        and start the reader and keep-alive threads.

        ``zenoh/NAME`` (``zenoh/NAME?zenoh=ENDPOINT``, or the endpoint or JSON5 file as
        ``zenoh=``; default tcp/127.0.0.1:7447) gives a
        :class:`~robocli.devices.pioneer.over_zenoh.RemotePioneer`, the robot behind
        ``robocli bridge pioneer``: it has what a script drives with (``state``, ``pose``,
        ``battery``, ``enable_motors``, ``set_velocity``, ``stop``, ``wait_for_state``,
        listeners, ``close``), not the ARCOS-only commands. ``timeout`` and ``listeners``
        apply there; the link's own arguments (``subtype``, ``baudrate``...) are refused.

        ``subtype`` overrides the robot's own (conversion factors from
        :data:`robocli.robots.pioneer.ROBOT_PARAMS`); ``params`` gives them outright.
        ``timeout`` bounds each step of connecting: opening the port, each handshake reply,
        the first SIP. ``sip_timeout``: a session without SIPs for that long has lost the
        robot. ``deadman``: stop the robot when no motion command came for that many seconds.
        Serial ports start at ``baudrate`` (default 9600; ``baud`` is its deprecated old
        name) and probe the other rates when the robot stays silent;
        ``switch_baud`` (e.g. 38400) moves the link there with HOSTBAUD after CONFIG, when
        the robot allows it. Raises :class:`TransportError` (unreachable),
        :class:`TimeoutError` (no robot answering), :class:`DeviceError` (the robot
        refused: busy with another client), :class:`UnknownRobotError` (no parameters for
        its subtype). ``laser=True`` starts a simulator's laser with the vendor SDK's
        defaults (``robot.sim.start_laser()``; a :class:`DeviceError` on a real robot).
        """
        rate = renamed_argument("Pioneer.connect", "baud", "baudrate", baud, baudrate, 9600)
        _check_seconds(timeout=timeout, sip_timeout=sip_timeout, keepalive=keepalive)
        where = parse_device_url(url, what="Pioneer URL")
        options: dict[str, Any] = {
            "subtype": subtype, "params": params, "switch_baud": switch_baud,
            "timeout": timeout, "sip_timeout": sip_timeout, "keepalive": keepalive,
            "deadman": deadman, "require_config": require_config, "listeners": listeners,
            "laser": laser,
        }  # fmt: skip
        if where.kind == "sim":
            return simulators.connect_to(  # type: ignore[no-any-return]
                "pioneer", where, lambda sim: cls.connect(sim.url, **options)
            )
        if where.kind == "zenoh":
            not_over_zenoh(url, "Pioneer", subtype=subtype, params=params, baudrate=baudrate,
                           baud=baud, switch_baud=switch_baud, deadman=deadman,
                           require_config=require_config, laser=laser)  # fmt: skip
            # imported here: it imports this package's modules
            from robocli.devices.pioneer.over_zenoh import RemotePioneer

            remote = RemotePioneer.connect(url, zenoh, timeout=timeout, listeners=listeners)
            return cast("Pioneer", remote)  # the driving surface, duck-typed (see above)
        if zenoh is not None:
            raise InvalidArgument(f"{url!r}: zenoh= is for a zenoh/NAME URL")
        transport = open_transport(where.target, baudrate=rate, timeout=timeout)
        return cls.from_transport(transport, **options)

    @classmethod
    def from_transport(
        cls,
        transport: Transport,
        *,
        subtype: str | None = None,
        params: RobotParams | None = None,
        switch_baud: int | None = None,
        timeout: float = 5.0,
        sip_timeout: float = 8.0,
        keepalive: float = 0.4,
        deadman: float | None = None,
        require_config: bool = False,
        listeners: Iterable[PacketListener] = (),
        laser: bool = False,
    ) -> Pioneer:
        """Like :meth:`connect` over an already open transport (a pipe, a wrapped or
        fault-injecting stream). The Pioneer owns it from now on and closes it."""
        try:
            _check_seconds(timeout=timeout, sip_timeout=sip_timeout, keepalive=keepalive)
        except InvalidArgument:
            transport.close()
            raise
        # The handshake reads its replies itself; what else arrives once OPEN went out (the
        # robot's first SIPs) is kept and handed to the client when it starts.
        early: list[tuple[bytes, float]] = []
        session = Session(
            transport,
            Framer("arcos"),
            on_frame=lambda frame, t: early.append((frame, t)) if len(early) < 64 else None,
            payload_of=link.payload_of,
            name_of=link.name_of,
            emergency_stop=lambda: link.EMERGENCY_STOP,
            stats=PioneerStats(),
            name="pioneer",
        )
        for listener in listeners:
            session.listeners.add(listener)
        opened = False
        try:
            identity = link.handshake(session, timeout)
            chosen = params or link.params_for(subtype or identity.subtype, identity)
            early.clear()
            session.send(arcos.encode_command(Command.OPEN, 1))
            opened = True
            config = link.request_config(session, 1.0)
            if config is None and require_config:
                raise DeviceError(f"{transport.url}: the robot sent no CONFIG packet")
            if switch_baud is not None:
                link.switch_baud(session, config, switch_baud)
        except BaseException:
            session.close(link.STOP_SEQUENCE if opened else ())
            raise
        robot = cls(
            session,
            identity=identity,
            params=chosen,
            config=config,
            sip_timeout=sip_timeout,
            keepalive=keepalive,
            deadman=deadman,
        )
        try:
            for frame, t in early:
                robot._on_frame(frame, t)
            if robot.stats.sips == 0:  # connecting ends with the first SIP, within timeout
                robot.wait_for_sip(timeout=max(timeout, 1.0))
            if laser:
                robot._simulated.start_laser()
        except BaseException:
            robot.close()
            raise
        log.info(
            "connected to %s (%s %s) on %s",
            identity.name,
            identity.type,
            chosen.subtype,
            transport.url,
        )
        return robot

    # ------------------------------------------------------------------ state

    @property
    def state(self) -> PioneerState:
        """The latest SIP in SI units. Raises if the link is lost or SIPs stopped."""
        with self._session.cond:
            self._session.check()
            return self._current_state()

    @property
    def pose(self) -> tuple[float, float, float]:
        """Odometry pose (x m, y m, th rad)."""
        return self.state.pose

    @property
    def sonar(self) -> tuple[float, ...]:
        """Sonar ranges in metres, by sonar index (nan before the first reading)."""
        return self.state.sonar[: len(self.params.sonar)]

    @property
    def battery(self) -> float:
        """Battery voltage (V) of the latest SIP."""
        return self.state.battery

    @property
    def is_simulator(self) -> bool:
        """The robot is a simulator: it says so in its name or its CONFIG serial (``SIM``),
        the vendor SDK's test before it asks for the simulated laser."""
        return is_simulator(self.identity.name, self.config)

    @property
    def sim(self) -> PioneerSimulator | None:
        """What only a simulator offers (its laser, status, teleporting): a
        :class:`~robocli.devices.pioneer.simulated.PioneerSimulator`; None on a real robot."""
        return self._simulated if self.is_simulator else None

    def _on_laser(self, ptype: int, body: bytes, now: float) -> None:
        self._simulated._on_laser(ptype, body, now)

    def wait_for_sip(self, timeout: float | None = None) -> PioneerState:
        """Block until the next SIP arrives and return it (``timeout`` defaults to
        ``sip_timeout``)."""
        limit = self.sip_timeout if timeout is None else timeout
        deadline = time.monotonic() + limit
        cond = self._session.cond
        with cond:
            count = self.stats.sips
            while True:
                self._session.check()
                if self.stats.sips > count:
                    return self._current_state()
                left = deadline - time.monotonic()
                if left <= 0:
                    if timeout is None:  # the robot's silence limit: as the supervisor says it
                        raise self._keeper.silence_error()
                    raise TimeoutError(f"{self.transport.url}: no SIP within {limit:g} s")
                cond.wait(left)

    def wait_for_state(self, timeout: float | None = None) -> PioneerState:
        """The next state, as every client spells it (:class:`~robocli.bridge.RemotePioneer`,
        the arm): :meth:`wait_for_sip`."""
        return self.wait_for_sip(timeout)

    def snapshot(self) -> dict[str, Any]:
        """Identity, parameters, the latest state and link counters as plain data (JSON-ready)."""
        state = self.state
        data = {k: getattr(state, k) for k in state.__dataclass_fields__}
        data["sonar"] = [None if math.isnan(r) else r for r in self.sonar]
        data.pop("sonar_time")
        stats = self.stats.as_dict()
        return {
            "identity": {
                "name": self.identity.name,
                "type": self.identity.type,
                "subtype": self.identity.subtype,
            },
            "url": self.transport.url,
            "params": self.params.subtype,
            "state": data,
            "link": {k: stats[k] for k in ("sips", "bad_checksums", "dropped_bytes", "keepalives")},
        }

    def add_listener(self, listener: Callable[..., None], *, kind: str = "frames"
                     ) -> ListenerHandle:  # fmt: skip
        """Call ``listener`` with what ``kind`` names and return a handle whose ``remove()``
        takes it off: ``"frames"`` (every packet sent or received: ``(direction "tx"/"rx",
        payload, t)``), ``"laser"`` (each complete simulated laser scan, a
        :class:`LaserScan`) or ``"watchdog"`` (each :class:`WatchdogTrip`). Listeners run in
        the thread that sent or read the packet: keep them short. One that raises is logged
        once with its traceback, counted in ``stats.listener_errors``, and never stops the
        client."""
        return self._add_listener(listener, kind)

    def _listeners_of(self, kind: str) -> Listeners[Any]:
        pick_kind(kind, ("frames", "laser", "watchdog"), "Pioneer")
        found: dict[str, Listeners[Any]] = {
            "frames": self._session.listeners, "laser": self._simulated.listeners,
            "watchdog": self._keeper.listeners,
        }  # fmt: skip
        return found[kind]

    # ------------------------------------------------------------------ closing

    def close(self, *, stop: bool = True) -> None:
        """Stop the robot, disable the motors, CLOSE the session and the port, within about
        2 s whatever state the link is in; then the simulator of a ``sim://`` URL.
        Idempotent. A Pioneer is always stopped (``stop=False`` is refused): its watchdog
        would stop it anyway, 2 s later."""
        if not stop:
            raise InvalidArgument("a Pioneer is always stopped on close (stop=False refused)")
        try:
            self._session.close(link.STOP_SEQUENCE)
        finally:
            close_simulator(self)

    #: the in-process simulator of a ``sim://`` URL (None otherwise), closed with the robot
    simulator: simulators.Simulator | None = None

    def __repr__(self) -> str:
        i = self.identity
        return f"<Pioneer {i.name} {i.subtype} on {self.transport.url}>"


def _check_seconds(**durations: float) -> None:
    """Each duration a number of seconds in (0, :data:`MAX_WAIT_S`], or
    :class:`InvalidArgument` (sockets and locks overflow on larger ones)."""
    for name, value in durations.items():
        if not 0 < _finite(name, value) <= MAX_WAIT_S:
            raise InvalidArgument(f"{name} must be within 0..{MAX_WAIT_S:g} s, not {value!r}")


#: The longest wait a duration argument may ask for (s): 11 days.
MAX_WAIT_S = 1e6


__all__ = ["Pioneer", "PioneerStats", "WatchdogListener", "WatchdogTrip", "WatchdogTripped"]
