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

Clocks: every ``t`` here is ``time.monotonic()`` at reception on this computer.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import deque
from collections.abc import Iterable
from typing import Any

from robocli.core import Framer
from robocli.devices.pioneer import link
from robocli.devices.pioneer.simulated import SimulatorFeatures
from robocli.devices.pioneer.state import (
    Odometry,
    PioneerState,
    RobotIdentity,
    build_state,
    sip_essentials,
    sip_motors_on,
)
from robocli.devices.session import FrameListener, LinkStats, Session
from robocli.errors import DeviceError, InvalidArgument, ProtocolError, TimeoutError
from robocli.protocols import arcos
from robocli.protocols.arcos import Command, PacketType
from robocli.robots.geometry import wrap_pi
from robocli.robots.pioneer import RobotParams
from robocli.transports import Transport, open_transport

log = logging.getLogger("robocli.devices.pioneer")

#: Listener signature: (direction "tx"/"rx", payload = type byte + data, monotonic time).
PacketListener = FrameListener

_HISTORY = 100_000  #: samples kept in each timing history of :class:`PioneerStats`
_PULSE = arcos.encode_command(Command.PULSE)


class PioneerStats(LinkStats):
    """Link counters (see :class:`~robocli.devices.session.LinkStats`) plus the Pioneer's:
    SIPs received, keep-alives sent, dead-man stops, laser scans completed and dropped
    (incomplete or garbled), and bounded timing histories."""

    _COUNTERS: tuple[str, ...] = (
        *LinkStats._COUNTERS, "sips", "keepalives", "deadman_stops", "laser_scans",
        "laser_dropped",
    )  # fmt: skip

    def __init__(self) -> None:
        super().__init__()
        self.sips = 0
        self.keepalives = 0
        self.deadman_stops = 0
        self.laser_scans = 0
        self.laser_dropped = 0
        #: reader CPU seconds per SIP (decode + state update; thread CPU time, so waiting
        #: for the GIL is not counted), most recent last
        self.sip_work: deque[float] = deque(maxlen=_HISTORY)
        #: monotonic send times of keep-alive packets (PULSE or set-point refresh)
        self.keepalive_times: deque[float] = deque(maxlen=_HISTORY)
        #: monotonic send times of every packet (what the robot's watchdog sees)
        self.tx_times: deque[float] = deque(maxlen=_HISTORY)
        #: monotonic receive times of SIPs
        self.sip_times: deque[float] = deque(maxlen=_HISTORY)


class Pioneer(SimulatorFeatures):
    """A connected Pioneer. Make one with :meth:`connect`; use it as a context manager.

    With a simulator also: its laser (:meth:`start_laser`, :attr:`laser`, :meth:`on_laser`)
    and its status (:meth:`sim_status`), from :class:`SimulatorFeatures`."""

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
        self._last_app_command = now
        # set-points re-sent by the keep-alive: list of (command, arg) in send order
        self._setpoints: list[tuple[int, int]] = []
        self._setpoint_lock = threading.Lock()
        self._clamp_warned: set[str] = set()
        self._motors_off_warned = False
        self._enable_sent = False  # ENABLE 1 went out (the next SIPs may not show it yet)
        self._init_simulated()
        session.on_frame = self._on_frame
        session.on_sent = self.stats.tx_times.append  # the time of every packet sent
        session.add_task("keepalive", self._keepalive_step)
        self._supervisor = session.add_task("supervisor", self._supervise_step)
        session.start()

    # ------------------------------------------------------------------ connecting

    @classmethod
    def connect(
        cls,
        url: str,
        *,
        subtype: str | None = None,
        params: RobotParams | None = None,
        baud: int = 9600,
        switch_baud: int | None = None,
        timeout: float = 5.0,
        sip_timeout: float = 8.0,
        keepalive: float = 0.4,
        deadman: float | None = None,
        require_config: bool = False,
        listeners: Iterable[PacketListener] = (),
        laser: bool = False,
    ) -> Pioneer:
        """Open ``url`` (``/dev/ttyUSB0``, ``COM1``, ``tcp://host:8101``, pyserial URLs),
        run the ARCOS handshake and start the reader and keep-alive threads.

        ``subtype`` overrides the robot's own (conversion factors from
        :data:`robocli.robots.pioneer.ROBOT_PARAMS`); ``params`` gives them outright.
        ``timeout`` bounds each step of connecting: opening the port, each handshake reply,
        the first SIP. ``sip_timeout``: a session without SIPs for that long has lost the
        robot. ``deadman``: stop the robot when no motion command came for that many seconds.
        Serial ports start at ``baud`` and probe the other rates when the robot stays silent;
        ``switch_baud`` (e.g. 38400) moves the link there with HOSTBAUD after CONFIG, when
        the robot allows it. Raises :class:`TransportError` (unreachable),
        :class:`TimeoutError` (no robot answering), :class:`DeviceError` (the robot
        refused: busy with another client), :class:`UnknownRobotError` (no parameters for
        its subtype). ``laser=True`` starts a simulator's laser with the vendor SDK's
        defaults (:meth:`start_laser`; a :class:`DeviceError` on a real robot).
        """
        _check_seconds(timeout=timeout, sip_timeout=sip_timeout, keepalive=keepalive)
        transport = open_transport(url, baudrate=baud, timeout=timeout)
        return cls.from_transport(
            transport,
            subtype=subtype,
            params=params,
            switch_baud=switch_baud,
            timeout=timeout,
            sip_timeout=sip_timeout,
            keepalive=keepalive,
            deadman=deadman,
            require_config=require_config,
            listeners=listeners,
            laser=laser,
        )

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
                robot.start_laser()
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
    def connected(self) -> bool:
        """True while the session runs: False once the link failed, SIPs stopped or
        :meth:`close` began."""
        return self._session.alive

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
                    raise TimeoutError(f"{self.transport.url}: no SIP within {limit:g} s")
                cond.wait(left)

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

    def add_listener(self, listener: PacketListener) -> None:
        """Call ``listener(direction, payload, t)`` for every packet sent ("tx") or received
        ("rx"). Listeners run in the thread that sent or read the packet: keep them short.
        One that raises is logged once with its traceback, counted in
        ``stats.listener_errors``, and never stops the client."""
        self._session.listeners.add(listener)

    def remove_listener(self, listener: PacketListener) -> None:
        self._session.listeners.remove(listener)

    # ------------------------------------------------------------------ commands (SI units)

    def send_command(self, command: int, arg: int | str | bytes | None = None) -> None:
        """Send one raw ARCOS command (numbers in :class:`~robocli.protocols.arcos.Command`)."""
        self._session.send(arcos.encode_command(command, arg))

    def enable_motors(self) -> None:
        """Power the motors (ENABLE 1). A robot starts with them off, and ignores motion
        commands until they are on; the e-stop button also turns them off."""
        self.send_command(Command.ENABLE, 1)
        self._enable_sent = True

    def disable_motors(self) -> None:
        """Stop keeping set-points alive and power the motors off (ENABLE 0)."""
        self._set_setpoints([])
        self._enable_sent = False
        self.send_command(Command.ENABLE, 0)

    def set_velocity(self, v: float, w: float = 0.0) -> None:
        """Translational (m/s) and rotational (rad/s, CCW +) velocity; re-sent by the
        keep-alive until changed.

        Values beyond the robot's limits (CONFIG's ``transvel_top``/``rotvel_top``, else the
        model's) are clamped to them with one warning, as the vendor SDK does: ``200`` is
        mm/s in the vendor's units but 200 m/s here. Raises
        :class:`~robocli.errors.InvalidArgument` for anything that is not a finite number.
        """
        v = self._limited("v", v, self.max_velocity, "m/s")
        w = self._limited("w", w, self.max_rot_velocity, "rad/s")
        vel = _clamp_int(round(v * 1000.0))
        rvel = _clamp_int(round(math.degrees(w)))
        self._command_motion([(Command.VEL, vel), (Command.RVEL, rvel)])

    @property
    def max_velocity(self) -> float:
        """The robot's top translational speed (m/s): CONFIG's ``transvel_top``, else the
        model's."""
        top = (self.config or {}).get("transvel_top")
        return top / 1000.0 if top else self.params.max_velocity

    @property
    def max_rot_velocity(self) -> float:
        """The robot's top rotational speed (rad/s): CONFIG's ``rotvel_top``, else the
        model's."""
        top = (self.config or {}).get("rotvel_top")
        return math.radians(top) if top else self.params.max_rot_velocity

    def _limited(self, name: str, value: float, limit: float, unit: str) -> float:
        value = _finite(name, value)
        if abs(value) <= limit:
            return value
        if name not in self._clamp_warned:
            self._clamp_warned.add(name)
            log.warning(
                "%s=%g %s is beyond the robot's limit of %g %s: clamped (robocli takes SI "
                "units; this warning is given once)", name, value, unit, limit, unit,
            )  # fmt: skip
        return math.copysign(limit, value)

    def set_wheel_velocities(self, left: float, right: float) -> None:
        """Independent wheel speeds (m/s) with VEL2, in steps of ``vel2_divisor`` mm/s."""
        div = self.params.vel2_divisor
        hi = max(-128, min(127, round(left * 1000.0 / div)))
        lo = max(-128, min(127, round(right * 1000.0 / div)))
        value = int.from_bytes(bytes((lo & 0xFF, hi & 0xFF)), "little", signed=True)
        self._command_motion([(Command.VEL2, value)])

    def move(self, distance: float) -> None:
        """Drive ``distance`` metres (negative: backwards) at the SETV speed, then stop."""
        self._command_motion([], (Command.MOVE, _clamp_int(round(distance * 1000.0))))

    def set_heading(self, th: float) -> None:
        """Turn to absolute odometry heading ``th`` (rad)."""
        deg = round(math.degrees(wrap_pi(th)))
        self._command_motion([], (Command.HEAD, deg))

    def turn(self, dth: float) -> None:
        """Turn by ``dth`` radians relative to the current heading (CCW +)."""
        self._command_motion([], (Command.DHEAD, _clamp_int(round(math.degrees(dth)))))

    def stop(self) -> None:
        """Stop translation and rotation with the normal deceleration (VEL 0 + RVEL 0,
        as the vendor SDK does; the zero set-points are kept alive)."""
        self._command_motion([(Command.VEL, 0), (Command.RVEL, 0)])

    def estop(self) -> None:
        """Emergency stop: maximum deceleration."""
        self._set_setpoints([(Command.VEL, 0), (Command.RVEL, 0)])
        self.send_command(Command.ESTOP)

    def set_max_velocity(self, v: float | None = None, w: float | None = None) -> None:
        """Maximum translational (m/s, also MOVE speed) and rotational (rad/s) velocity."""
        if v is not None:
            self.send_command(Command.SETV, _clamp_int(round(abs(v) * 1000.0)))
        if w is not None:
            self.send_command(Command.SETRV, _clamp_int(round(math.degrees(abs(w)))))

    def set_acceleration(
        self,
        trans: float | None = None,
        rot: float | None = None,
        *,
        trans_decel: float | None = None,
        rot_decel: float | None = None,
    ) -> None:
        """Accelerations in m/s² and rad/s²; decelerations default to the accelerations."""
        for cmd, acc, dec in (
            (
                Command.SETA,
                trans,
                trans_decel,
            ),
            (Command.SETRA, rot, rot_decel),
        ):
            scale = 1000.0 if cmd == Command.SETA else math.degrees(1.0)
            if acc is not None:
                self.send_command(cmd, _clamp_int(round(abs(acc) * scale)))
            dec = acc if dec is None else dec
            if dec is not None:
                self.send_command(cmd, -_clamp_int(round(abs(dec) * scale)))

    def enable_sonar(self, on: bool = True) -> None:
        self.send_command(Command.SONAR, 1 if on else 0)

    def reset_odometry(self) -> None:
        """Zero the robot's odometry (SETO); the client pose restarts at (0, 0) at once,
        and follows the robot's counters again once it has applied the reset."""
        self.send_command(Command.SETO)
        with self._session.cond:
            self._odo.expect_reset(time.monotonic())

    def set_digital_out(self, mask: int, values: int) -> None:
        """Change the user digital outputs selected by ``mask`` to ``values``."""
        value = int.from_bytes(bytes((values & 0xFF, mask & 0xFF)), "little", signed=True)
        self.send_command(Command.DIGOUT, value)

    def select_analog(self, port: int) -> None:
        """Choose the analog port reported in every SIP (``state.analog``). Not on a
        simulator with a laser: there ADSEL's number (35) switches the laser."""
        self.send_command(Command.ADSEL, port)

    def request_io(self, mode: int = 1) -> None:
        """IO packets: 0 stop, 1 one, 2 continuous (decoded into :attr:`io`)."""
        self.send_command(Command.IOREQUEST, mode)

    def request_encoders(self, mode: int = 1) -> None:
        """Encoder packets: 0 stop, 1 one, 2 continuous (decoded into :attr:`encoders`)."""
        self.send_command(Command.ENCODER, mode)

    def say(self, tones: Iterable[tuple[float, int]]) -> None:
        """Play tones on the piezo: (duration s, tone 0..127) pairs, at most 20."""
        data = bytearray()
        for duration, tone in list(tones)[:20]:
            data += bytes((max(1, min(255, round(duration / 0.020))), tone & 0xFF))
        self.send_command(Command.SAY, bytes(data))

    def request_config(self, timeout: float = 1.0) -> dict[str, Any]:
        """Ask for a CONFIG packet and return its fields (raw units, as the robot sends).
        The caller reads the reply itself; raises :class:`TimeoutError` or the link's error,
        never returns an older CONFIG."""
        frame = self._session.request(link.CONFIG_REQUEST, link.is_config, timeout)
        if frame[3:-2] != self._config_raw:  # it did not decode (counted in decode_errors)
            raise ProtocolError(f"{self.transport.url}: the CONFIG reply did not decode")
        assert self.config is not None  # stored from this very frame by _on_frame
        return self.config

    def set_simulator_pose(self, x: float, y: float, th: float) -> None:
        """Simulators only (MobileSim, robocli sim): teleport the true pose (m, m, rad)."""
        self._session.send(
            arcos.encode_sim_pose(round(x * 1000), round(y * 1000), round(math.degrees(th)))
        )

    # ------------------------------------------------------------------ closing

    def close(self) -> None:
        """Stop the robot, disable the motors, CLOSE the session and the port, within about
        2 s whatever state the link is in. Idempotent."""
        self._session.close(link.STOP_SEQUENCE)

    def __enter__(self) -> Pioneer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        i = self.identity
        return f"<Pioneer {i.name} {i.subtype} on {self.transport.url}>"

    # ------------------------------------------------------------------ internals

    def _set_setpoints(self, setpoints: list[tuple[int, int]]) -> None:
        with self._setpoint_lock:
            self._setpoints = setpoints

    def _command_motion(
        self, setpoints: list[tuple[int, int]], once: tuple[int, int] | None = None
    ) -> None:
        """Send motion commands now; ``setpoints`` are then kept alive, ``once`` is not."""
        self._session.check()
        self._last_app_command = time.monotonic()
        if not (self._motors_off_warned or self._enable_sent or self._motors_on()):
            self._motors_off_warned = True
            log.warning(
                "%s: the motors are disabled, so the robot will not move: call "
                "enable_motors() first (state.motors_enabled tells; warned once)",
                self.transport.url,
            )
        self._set_setpoints(setpoints)
        for cmd, arg in setpoints:
            self._session.send(arcos.encode_command(cmd, arg))
        if once is not None:
            self._session.send(arcos.encode_command(*once))
        if self.deadman is not None:
            self._supervisor.wake()

    def _motors_on(self) -> bool:
        """The motors flag of the latest SIP (no decode: one byte of the body)."""
        sip = self._sip
        if sip is None:
            return True
        return sip_motors_on(sip[0])

    def _on_frame(self, frame: bytes, now: float) -> None:
        """Every received frame, in the reader thread or a caller waiting for a reply."""
        ptype = frame[3]
        if ptype & 0xF0 == 0x30:
            start = time.thread_time()
            self._on_sip(frame, now)
            self.stats.sip_work.append(time.thread_time() - start)
        elif ptype == PacketType.CONFIG:
            self._store_config(link.payload_of(frame))
        elif ptype == PacketType.IO:
            self.io = link.parse_body(arcos.IO, link.payload_of(frame), "IO")
        elif ptype == PacketType.ENCODER:
            enc = link.parse_body(arcos.ENCODER, link.payload_of(frame), "ENCODER")
            self.encoders = (int(enc["left"]), int(enc["right"]))
        elif ptype == PacketType.BATTERY:
            self.battery_info = link.parse_body(arcos.BATTERY, link.payload_of(frame), "BATTERY")
        elif ptype in (PacketType.SIM_LASER, PacketType.SIM_LASER_A):
            self._on_laser(ptype, frame[4:-2], now)

    def _store_config(self, payload: bytes) -> None:
        if payload != self._config_raw:  # construct is slow; CONFIG rarely changes
            self.config = dict(link.parse_body(arcos.CONFIG, payload, "CONFIG"))
            self._config_raw = payload

    def _on_sip(self, frame: bytes, now: float) -> None:
        # The per-SIP work is kept to the odometry counters and the sonar readings; the rest
        # of the SIP is decoded, and the SI-unit state built, when the program asks for it.
        body = frame[4:-2]
        x, y, readings = sip_essentials(body)
        conv = self.params.range_conv / 1000.0
        sonar, sonar_t = self._sonar, self._sonar_t
        n_sonar = len(sonar)
        cond = self._session.cond
        with cond:
            for number, rng in readings:
                if number < n_sonar:
                    sonar[number] = rng * conv
                    sonar_t[number] = now
            self._sip = (body, now, self._odo.update(x, y, now))
            self.stats.sips += 1
            self.stats.sip_times.append(now)
            self._state = None
            self._last_sip = now
            cond.notify_all()

    def _current_state(self) -> PioneerState:
        """The latest SIP as a :class:`PioneerState` (built once per SIP; hold the cond)."""
        if self._state is None:
            if self._sip is None:
                raise TimeoutError(f"{self.transport.url}: no SIP received yet")
            body, now, odo = self._sip
            self._state = build_state(
                arcos.decode_sip(body), now, odo, tuple(self._sonar), tuple(self._sonar_t),
                self.params, self.stats.sips,
            )  # fmt: skip
        return self._state

    def _keepalive_step(self) -> float:
        """Re-send the set-points (PULSE when there are none) once nothing was sent for
        ``keepalive`` s; sleep until then."""
        now = time.monotonic()
        due = self._session.last_tx + self.keepalive
        if now < due:
            return due - now
        with self._setpoint_lock:
            setpoints = list(self._setpoints)
        self.stats.add("keepalives")
        self.stats.keepalive_times.append(now)
        if setpoints:
            for cmd, arg in setpoints:
                self._session.send(arcos.encode_command(cmd, arg))
        else:
            self._session.send(_PULSE)
        return self.keepalive

    def _supervise_step(self) -> float:
        """No SIP for ``sip_timeout``: fail (the session stops the robot). With a dead-man:
        stop a moving robot ``deadman`` s after the last motion command."""
        now = time.monotonic()
        silent_at = self._last_sip + self.sip_timeout
        if now > silent_at:
            self._session.fail(
                TimeoutError(
                    f"{self.transport.url}: no SIP for {self.sip_timeout:g} s "
                    "(robot off, cable unplugged, or session closed)"
                )
            )
            return self.sip_timeout
        wait = silent_at - now
        if self.deadman is not None:
            with self._setpoint_lock:
                moving = any(arg != 0 for _, arg in self._setpoints)
            due = self._last_app_command + self.deadman
            if moving and now >= due:
                log.warning("dead-man: no motion command for %.2f s, stopping", now - due
                            + self.deadman)  # fmt: skip
                self.stats.add("deadman_stops")
                self.stop()
            elif moving:
                wait = min(wait, due - now)
        return max(0.001, wait)


def _finite(name: str, value: object) -> float:
    """``value`` as a finite float, or :class:`InvalidArgument` naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InvalidArgument(f"{name} must be a number, not {value!r}")
    if not math.isfinite(value):
        raise InvalidArgument(f"{name} must be a finite number, not {value!r}")
    return float(value)


def _check_seconds(**durations: float) -> None:
    """Each duration a number of seconds in (0, :data:`MAX_WAIT_S`], or
    :class:`InvalidArgument` (sockets and locks overflow on larger ones)."""
    for name, value in durations.items():
        if not 0 < _finite(name, value) <= MAX_WAIT_S:
            raise InvalidArgument(f"{name} must be within 0..{MAX_WAIT_S:g} s, not {value!r}")


#: The longest wait a duration argument may ask for (s): 11 days.
MAX_WAIT_S = 1e6


def _clamp_int(value: int) -> int:
    return max(-0x7FFF, min(0x7FFF, value))


__all__ = ["Pioneer", "PioneerStats"]
