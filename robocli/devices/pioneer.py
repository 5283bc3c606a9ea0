"""Pioneer robots (P3-DX family) over ARCOS: serial port or TCP (MobileSim/robocli sim: 8101).

>>> with Pioneer.connect("tcp://127.0.0.1:8101") as robot:   # doctest: +SKIP
...     robot.enable_motors()
...     robot.set_velocity(0.2, 0.0)          # m/s, rad/s
...     x, y, th = robot.pose                 # m, m, rad (odometry)

The client does what the vendor SDK does to keep a robot safe and alive: a reader thread
decodes every SIP into SI units; set-points are re-sent at least every ``keepalive`` seconds
and PULSE goes out when nothing else was sent, so the robot's 2 s watchdog never trips while
the program runs; an optional dead-man stops the robot if the program stops commanding;
leaving the ``with`` block, Ctrl-C, an exception or a lost link stops the robot and CLOSEs.
No SIP for ``sip_timeout`` seconds raises :class:`robocli.errors.TimeoutError` to the caller.

Clocks: every ``t`` here is ``time.monotonic()`` at reception on this computer.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import Counter, deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

from robocli.core import Framer
from robocli.errors import (
    ConnectionLost,
    DeviceError,
    ProtocolError,
    RobocliError,
    TimeoutError,
    UnknownRobotError,
)
from robocli.protocols import arcos
from robocli.protocols.arcos import Command, PacketType, RobotParams
from robocli.protocols.common import plain
from robocli.transports import Transport, open_transport

log = logging.getLogger("robocli.devices.pioneer")

#: Listener signature: (direction "tx"/"rx", payload = type byte + data, monotonic time).
PacketListener = Callable[[str, bytes, float], None]


@dataclass(frozen=True)
class RobotIdentity:
    """What the robot says of itself in the SYNC2 reply."""

    name: str
    type: str
    subtype: str


@dataclass(frozen=True)
class PioneerState:
    """One SIP in SI units. Pose is odometry (15-bit counters unwrapped)."""

    t: float  #: monotonic receive time (s)
    x: float  #: m
    y: float  #: m
    th: float  #: rad, in [-pi, pi)
    v: float  #: m/s, mean of the wheel speeds
    w: float  #: rad/s, counter-clockwise positive
    left_velocity: float  #: m/s
    right_velocity: float  #: m/s
    battery: float  #: V
    state_of_charge: float | None  #: 0..1, None when the robot does not model it
    charge_state: int | None
    motors_enabled: bool
    estop: bool
    sonar_enabled: bool
    stall_left: bool
    stall_right: bool
    bumpers_front: int  #: bit mask of the front bump ring (bit 0 = first switch)
    bumpers_rear: int
    sonar: tuple[float, ...]  #: m, per sonar index; nan until first reading
    sonar_time: tuple[float, ...]  #: monotonic time each range was last updated
    digin: int
    digout: int
    analog: float  #: V, the port chosen with select_analog
    temperature: float | None  #: deg C
    sip_count: int

    @property
    def pose(self) -> tuple[float, float, float]:
        return (self.x, self.y, self.th)

    @property
    def bumped(self) -> bool:
        return bool(self.bumpers_front or self.bumpers_rear)

    @property
    def stalled(self) -> bool:
        return self.stall_left or self.stall_right


@dataclass
class LinkStats:
    """Counters of the byte stream and the packets (what a lab user checks first)."""

    sips: int = 0
    bad_checksums: int = 0
    dropped_bytes: int = 0
    sent: Counter[str] = field(default_factory=Counter)
    received: Counter[str] = field(default_factory=Counter)
    keepalives: int = 0
    deadman_stops: int = 0
    #: CPU seconds the reader thread spent per SIP (decode + state update), most recent last;
    #: thread CPU time, so waiting for the GIL (e.g. an in-process simulator) is not counted
    sip_work: deque[float] = field(default_factory=lambda: deque(maxlen=100_000))
    #: monotonic send times of keep-alive packets (PULSE or set-point refresh)
    keepalive_times: deque[float] = field(default_factory=lambda: deque(maxlen=100_000))
    #: monotonic send times of every packet (what the robot's watchdog sees)
    tx_times: deque[float] = field(default_factory=lambda: deque(maxlen=100_000))
    #: monotonic receive times of SIPs
    sip_times: deque[float] = field(default_factory=lambda: deque(maxlen=100_000))


def _wrap_pi(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


class _Odometry:
    """Unwraps the 15-bit x/y counters as ARIA does (a jump of > 0x1000 units is a wrap)."""

    def __init__(self) -> None:
        self.raw: tuple[int, int] | None = None
        self.x = 0
        self.y = 0

    def update(self, rx: int, ry: int) -> tuple[int, int]:
        rx &= 0x7FFF
        ry &= 0x7FFF
        if self.raw is None:
            self.x, self.y = rx, ry
        else:
            self.x += self._delta(rx - self.raw[0])
            self.y += self._delta(ry - self.raw[1])
        self.raw = (rx, ry)
        return self.x, self.y

    @staticmethod
    def _delta(d: int) -> int:
        if d > 0x1000:
            d -= 0x8000
        elif d < -0x1000:
            d += 0x8000
        return d


class Pioneer:
    """A connected Pioneer. Make one with :meth:`connect`; use it as a context manager."""

    def __init__(
        self,
        transport: Transport,
        *,
        identity: RobotIdentity,
        params: RobotParams,
        config: dict[str, Any] | None,
        framer: Framer,
        sip_timeout: float = 8.0,
        keepalive: float = 0.4,
        deadman: float | None = None,
        listeners: Iterable[PacketListener] = (),
    ) -> None:
        self.transport = transport
        self.identity = identity
        self.params = params
        self.config = config
        self.sip_timeout = sip_timeout
        self.keepalive = keepalive
        self.deadman = deadman
        self.stats = LinkStats()
        self.io: dict[str, Any] | None = None  #: last IO packet (0xF0), raw fields
        self.encoders: tuple[int, int] | None = None  #: last encoder packet (0x90), ticks
        self.battery_info: dict[str, Any] | None = None
        self._framer = framer
        self._listeners: list[PacketListener] = list(listeners)
        self._odo = _Odometry()
        n_sonar = max(16, len(params.sonar))
        self._sonar = [math.nan] * n_sonar
        self._sonar_t = [math.nan] * n_sonar
        self._state: PioneerState | None = None  # built lazily from _sip
        self._sip: tuple[dict[str, Any], float, tuple[int, int]] | None = None
        self._cond = threading.Condition()
        self._config_event = threading.Event()
        self._config_raw = b""
        self._error: RobocliError | None = None
        self._closing = False
        self._last_tx = time.monotonic()
        self._last_rx = time.monotonic()
        self._last_app_command = time.monotonic()
        # set-points re-sent by the keep-alive: list of (command, arg) in send order
        self._setpoints: list[tuple[int, int]] = []
        self._setpoint_lock = threading.Lock()
        self._reader = threading.Thread(target=self._read_loop, name="pioneer-reader", daemon=True)
        self._keeper = threading.Thread(
            target=self._keep_loop, name="pioneer-keepalive", daemon=True
        )
        self._reader.start()
        self._keeper.start()

    # ------------------------------------------------------------------ connecting

    @classmethod
    def connect(
        cls,
        url: str,
        *,
        subtype: str | None = None,
        params: RobotParams | None = None,
        baud: int = 9600,
        timeout: float = 5.0,
        sip_timeout: float = 8.0,
        keepalive: float = 0.4,
        deadman: float | None = None,
        require_config: bool = False,
        listeners: Iterable[PacketListener] = (),
    ) -> Pioneer:
        """Open ``url`` (``/dev/ttyUSB0``, ``COM1``, ``tcp://host:8101``, pyserial URLs),
        run the ARCOS handshake and start the reader and keep-alive threads.

        ``subtype`` overrides the robot's own (conversion factors from
        :data:`robocli.protocols.arcos.ROBOT_PARAMS`); ``params`` gives them outright.
        ``deadman``: stop the robot when no motion command came for that many seconds.
        Raises :class:`TransportError` (unreachable), :class:`TimeoutError` (no robot
        answering), :class:`UnknownRobotError` (no parameters for its subtype).
        """
        transport = open_transport(url, baudrate=baud, timeout=timeout)
        return cls.from_transport(
            transport,
            subtype=subtype,
            params=params,
            timeout=timeout,
            sip_timeout=sip_timeout,
            keepalive=keepalive,
            deadman=deadman,
            require_config=require_config,
            listeners=listeners,
        )

    @classmethod
    def from_transport(
        cls,
        transport: Transport,
        *,
        subtype: str | None = None,
        params: RobotParams | None = None,
        timeout: float = 5.0,
        sip_timeout: float = 8.0,
        keepalive: float = 0.4,
        deadman: float | None = None,
        require_config: bool = False,
        listeners: Iterable[PacketListener] = (),
    ) -> Pioneer:
        """Like :meth:`connect` over an already open transport (a pipe, a wrapped or
        fault-injecting stream). The Pioneer owns it from now on and closes it."""
        link = _Link(transport, list(listeners))
        try:
            identity = link.handshake(timeout)
            chosen = params or _params_for(subtype or identity.subtype, identity)
            link.send(arcos.encode_command(Command.OPEN, 1))
            config = link.request_config(1.0)
            if config is None and require_config:
                raise DeviceError(f"{transport.url}: the robot sent no CONFIG packet")
        except BaseException:
            transport.close()
            raise
        robot = cls(
            transport,
            identity=identity,
            params=chosen,
            config=config,
            framer=link.framer,
            sip_timeout=sip_timeout,
            keepalive=keepalive,
            deadman=deadman,
            listeners=link.listeners,
        )
        try:
            robot.wait_for_sip(timeout=max(sip_timeout, 1.0))
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
        with self._cond:
            self._check()
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
        return self.state.battery

    @property
    def connected(self) -> bool:
        return self._error is None and not self._closing

    def wait_for_sip(self, timeout: float | None = None) -> PioneerState:
        """Block until the next SIP arrives and return it."""
        deadline = time.monotonic() + (self.sip_timeout if timeout is None else timeout)
        with self._cond:
            count = self.stats.sips
            while True:
                self._check()
                if self.stats.sips > count:
                    return self._current_state()
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(f"{self.transport.url}: no SIP within {timeout} s")
                self._cond.wait(min(left, 0.1))

    def snapshot(self) -> dict[str, Any]:
        """Identity, parameters, the latest state and link counters as plain data (JSON-ready)."""
        state = self.state
        data = {k: getattr(state, k) for k in state.__dataclass_fields__}
        data["sonar"] = [None if math.isnan(r) else r for r in self.sonar]
        data.pop("sonar_time")
        return {
            "identity": {
                "name": self.identity.name,
                "type": self.identity.type,
                "subtype": self.identity.subtype,
            },
            "url": self.transport.url,
            "params": self.params.subtype,
            "state": data,
            "link": {
                "sips": self.stats.sips,
                "bad_checksums": self.stats.bad_checksums,
                "dropped_bytes": self.stats.dropped_bytes,
                "keepalives": self.stats.keepalives,
            },
        }

    def add_listener(self, listener: PacketListener) -> None:
        """Call ``listener(direction, payload, t)`` for every packet sent ("tx") or received
        ("rx"). Listeners run in the reader thread: keep them short."""
        self._listeners.append(listener)

    # ------------------------------------------------------------------ commands (SI units)

    def send_command(self, command: int, arg: int | str | bytes | None = None) -> None:
        """Send one raw ARCOS command (numbers in :class:`~robocli.protocols.arcos.Command`)."""
        self._check()
        self._write(arcos.encode_command(command, arg))

    def enable_motors(self) -> None:
        self.send_command(Command.ENABLE, 1)

    def disable_motors(self) -> None:
        self._set_setpoints([])
        self.send_command(Command.ENABLE, 0)

    def set_velocity(self, v: float, w: float = 0.0) -> None:
        """Translational (m/s) and rotational (rad/s, CCW +) velocity; re-sent by the
        keep-alive until changed."""
        vel = _clamp_int(round(v * 1000.0))
        rvel = _clamp_int(round(math.degrees(w)))
        self._command_motion([(Command.VEL, vel), (Command.RVEL, rvel)])

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
        deg = round(math.degrees(_wrap_pi(th)))
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
        """Zero the robot's odometry; the client pose restarts at (0, 0, 0)."""
        self.send_command(Command.SETO)
        with self._cond:
            self._odo = _Odometry()

    def set_digital_out(self, mask: int, values: int) -> None:
        """Change the user digital outputs selected by ``mask`` to ``values``."""
        value = int.from_bytes(bytes((values & 0xFF, mask & 0xFF)), "little", signed=True)
        self.send_command(Command.DIGOUT, value)

    def select_analog(self, port: int) -> None:
        """Choose the analog port reported in every SIP (``state.analog``)."""
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
        """Ask for a CONFIG packet and return its fields (raw units, as the robot sends)."""
        self._config_event.clear()
        self.send_command(Command.CONFIG, 1)
        if not self._config_event.wait(timeout):
            self._check()
            raise TimeoutError(f"{self.transport.url}: no CONFIG reply within {timeout} s")
        assert self.config is not None
        return self.config

    def set_simulator_pose(self, x: float, y: float, th: float) -> None:
        """Simulators only (MobileSim, robocli sim): teleport the true pose (m, m, rad)."""
        self._check()
        self._write(
            arcos.encode_sim_pose(round(x * 1000), round(y * 1000), round(math.degrees(th)))
        )

    # ------------------------------------------------------------------ closing

    def close(self) -> None:
        """Stop the robot, disable the motors, CLOSE the session and the port. Idempotent."""
        if self._closing:
            return
        self._closing = True
        if self._error is None:
            try:
                self._write(arcos.encode_command(Command.VEL, 0))
                self._write(arcos.encode_command(Command.RVEL, 0))
                self._write(arcos.encode_command(Command.ENABLE, 0))
                self._write(arcos.encode_command(Command.CLOSE, 1))
            except RobocliError as exc:
                log.warning("could not stop the robot cleanly: %s", exc)
        self.transport.close()
        for thread in (self._reader, self._keeper):
            if thread is not threading.current_thread():
                thread.join(timeout=2.0)

    def __enter__(self) -> Pioneer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        i = self.identity
        return f"<Pioneer {i.name} {i.subtype} on {self.transport.url}>"

    # ------------------------------------------------------------------ internals

    def _check(self) -> None:
        if self._error is not None:
            raise self._error
        if self._closing:
            raise ConnectionLost(f"{self.transport.url}: the connection is closed")

    def _write(self, data: bytes) -> None:
        try:
            self.transport.write(data)
        except ConnectionLost as exc:
            self._fail(exc)
            raise
        self._last_tx = time.monotonic()
        self.stats.tx_times.append(self._last_tx)
        payload = data[3:-2]
        self.stats.sent[arcos.packet_name(payload[0], from_client=True)] += 1
        for listener in self._listeners:
            listener("tx", payload, self._last_tx)

    def _set_setpoints(self, setpoints: list[tuple[int, int]]) -> None:
        with self._setpoint_lock:
            self._setpoints = setpoints

    def _command_motion(
        self, setpoints: list[tuple[int, int]], once: tuple[int, int] | None = None
    ) -> None:
        """Send motion commands now; ``setpoints`` are then kept alive, ``once`` is not."""
        self._check()
        self._last_app_command = time.monotonic()
        self._set_setpoints(setpoints)
        for cmd, arg in setpoints:
            self._write(arcos.encode_command(cmd, arg))
        if once is not None:
            self._write(arcos.encode_command(*once))

    def _fail(self, exc: RobocliError) -> None:
        with self._cond:
            if self._error is None and not self._closing:
                log.error("%s", exc)
                self._error = exc
            self._cond.notify_all()
        self._config_event.set()

    def _read_loop(self) -> None:
        """Blocking reads (a read with a timeout costs a poll per packet); the keep-alive
        thread watches for silence and closes the transport, which ends the read."""
        while not self._closing and self._error is None:
            try:
                data = self.transport.read(4096, timeout=None)
            except ConnectionLost as exc:
                if not self._closing:
                    self._fail(ConnectionLost(f"{self.transport.url}: link lost ({exc})"))
                return
            now = time.monotonic()
            for frame in self._framer.feed(data):
                self._handle(frame, now)
            st = self._framer.stats
            self.stats.bad_checksums = st.bad_checksums
            self.stats.dropped_bytes = st.dropped_bytes

    def _check_silence(self, now: float) -> bool:
        """No SIP for ``sip_timeout``: try to stop the robot, report, end the link."""
        if now - self._last_rx <= self.sip_timeout:
            return False
        self._fail(
            TimeoutError(
                f"{self.transport.url}: no SIP for {self.sip_timeout:g} s "
                "(robot off, cable unplugged, or session closed)"
            )
        )
        self._emergency_stop()
        self.transport.close()
        return True

    def _handle(self, frame: bytes, now: float) -> None:
        payload = frame[3:-2]
        ptype = payload[0]
        self.stats.received[arcos.packet_name(ptype, from_client=False)] += 1
        for listener in self._listeners:
            listener("rx", payload, now)
        try:
            if ptype & 0xF0 == 0x30:
                start = time.thread_time()
                self._on_sip(payload, now)
                self.stats.sip_work.append(time.thread_time() - start)
                self.stats.sip_times.append(now)
            elif ptype == PacketType.CONFIG:
                if payload != self._config_raw:  # construct is slow; CONFIG rarely changes
                    self.config = plain(arcos.CONFIG.parse(payload[1:]))
                    self._config_raw = payload
                self._config_event.set()
            elif ptype == PacketType.IO:
                self.io = plain(arcos.IO.parse(payload[1:]))
            elif ptype == PacketType.ENCODER:
                enc = arcos.ENCODER.parse(payload[1:])
                self.encoders = (int(enc.left), int(enc.right))
            elif ptype == PacketType.BATTERY:
                self.battery_info = plain(arcos.BATTERY.parse(payload[1:]))
        except Exception as exc:  # construct's errors: log, count, keep the session alive
            log.warning("undecodable packet 0x%02x: %s", ptype, exc)

    def _on_sip(self, payload: bytes, now: float) -> None:
        # The reader's per-SIP work is kept to decoding, odometry unwrapping and sonar
        # bookkeeping; the SI-unit snapshot is built when the program asks for it.
        sip = arcos.decode_sip(memoryview(payload)[1:])
        conv = self.params.range_conv / 1000.0
        sonar, sonar_t = self._sonar, self._sonar_t
        with self._cond:
            for number, rng in sip["sonar"]:
                if number < len(sonar):
                    sonar[number] = rng * conv
                    sonar_t[number] = now
            self._sip = (sip, now, self._odo.update(sip["x"], sip["y"]))
            self.stats.sips += 1
            self._state = None
            self._last_rx = now
            self._cond.notify_all()

    def _current_state(self) -> PioneerState:
        """The latest SIP as a :class:`PioneerState` (built once per SIP; hold ``_cond``)."""
        if self._state is None:
            assert self._sip is not None  # connect() waited for the first SIP
            self._state = self._build_state(*self._sip)
        return self._state

    def _build_state(self, sip: dict[str, Any], now: float, odo: tuple[int, int]) -> PioneerState:
        p = self.params
        lv = sip["lvel"] * p.vel_conv / 1000.0
        rv = sip["rvel"] * p.vel_conv / 1000.0
        rotvel = sip["rotvel"]
        w = math.radians(rotvel / 10.0) if rotvel is not None else (rv - lv) / 2 * p.diff_conv * 1e3
        batx10 = sip["battery_x10"]
        io = sip["io"] or {}
        soc = sip["state_of_charge"]
        temp = sip["temperature"]
        flags = sip["flags"]
        sb = sip["stall_bumpers"]
        return PioneerState(
            t=now,
            x=odo[0] * p.dist_conv / 1000.0,
            y=odo[1] * p.dist_conv / 1000.0,
            th=_wrap_pi(sip["th"] * p.angle_conv),
            v=(lv + rv) / 2,
            w=w,
            left_velocity=lv,
            right_velocity=rv,
            battery=(batx10 if batx10 else sip["battery"]) / 10.0,
            state_of_charge=soc / 100.0 if soc else None,
            charge_state=sip["charge_state"],
            motors_enabled=bool(flags & arcos.FLAG_MOTORS_ON),
            estop=bool(flags & arcos.FLAG_ESTOP),
            sonar_enabled=bool(flags & arcos.FLAG_SONAR_MASK),
            stall_left=bool(sb & arcos.STALL_LEFT),
            stall_right=bool(sb & arcos.STALL_RIGHT),
            bumpers_front=(sb & arcos.BUMPERS_FRONT_MASK) >> 9,
            bumpers_rear=(sb & arcos.BUMPERS_REAR_MASK) >> 1,
            sonar=tuple(self._sonar),
            sonar_time=tuple(self._sonar_t),
            digin=io.get("digin", 0),
            digout=io.get("digout", 0),
            analog=io.get("analog", 0) * 5.0 / 255.0,
            temperature=None if temp is None or temp == -127 else float(temp),
            sip_count=self.stats.sips,
        )

    def _keep_loop(self) -> None:
        """Re-send the set-points when nothing was sent for ``keepalive`` s (PULSE when there
        are none), run the dead-man and watch for silence. Sleeps until the next packet is due
        (<= 50 ms)."""
        while not self._closing and self._error is None:
            now = time.monotonic()
            time.sleep(max(0.0005, min(0.05, self._last_tx + self.keepalive - now)))
            now = time.monotonic()
            if self._check_silence(now):
                return
            try:
                with self._setpoint_lock:
                    setpoints = list(self._setpoints)
                moving = any(arg != 0 for _, arg in setpoints)
                idle = now - self._last_app_command
                if self.deadman is not None and moving and idle > self.deadman:
                    log.warning("dead-man: no motion command for %.2f s, stopping", idle)
                    self.stats.deadman_stops += 1
                    self.stop()
                    continue
                if now - self._last_tx >= self.keepalive:
                    self.stats.keepalives += 1
                    self.stats.keepalive_times.append(now)
                    if setpoints:
                        for cmd, arg in setpoints:
                            self._write(arcos.encode_command(cmd, arg))
                    else:
                        self._write(arcos.encode_command(Command.PULSE))
            except RobocliError:
                return

    def _emergency_stop(self) -> None:
        """Best effort on a dead link: try to stop the robot before giving up."""
        try:
            self.transport.write(arcos.encode_command(Command.VEL, 0))
            self.transport.write(arcos.encode_command(Command.RVEL, 0))
        except RobocliError:
            pass


# ---------------------------------------------------------------------- handshake


class _Link:
    """Synchronous packet I/O used during the handshake, before the reader thread runs."""

    def __init__(self, transport: Transport, listeners: list[PacketListener]) -> None:
        self.transport = transport
        self.framer = Framer("arcos")
        self.listeners = listeners
        self.pending: list[bytes] = []

    def send(self, data: bytes) -> None:
        self.transport.write(data)
        for listener in self.listeners:
            listener("tx", data[3:-2], time.monotonic())

    def next_packet(self, timeout: float) -> bytes | None:
        """The next frame's payload within ``timeout`` seconds, or None."""
        deadline = time.monotonic() + timeout
        while not self.pending:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            self.pending.extend(self.framer.feed(self.transport.read(4096, min(left, 0.1))))
        payload = self.pending.pop(0)[3:-2]
        for listener in self.listeners:
            listener("rx", payload, time.monotonic())
        return payload

    def flush(self) -> None:
        self.framer.reset()
        self.pending.clear()

    def handshake(self, timeout: float) -> RobotIdentity:
        """SYNC0/1/2 with retries; CLOSE a session that an earlier client left open."""
        deadline = time.monotonic() + timeout
        step = tried = 0
        while time.monotonic() < deadline:
            self.send(arcos.encode_command(step))
            tried += 1
            payload = self.next_packet(min(1.0, max(0.05, deadline - time.monotonic())))
            if payload is None or (payload[0] != step and payload[0] & 0xF0 != 0x30):
                step = 0  # silence or out of sequence: start again
                continue
            if payload[0] & 0xF0 == 0x30:
                log.info("robot is already in a session: sending CLOSE and re-syncing")
                self.send(arcos.encode_command(Command.CLOSE, 1))
                time.sleep(0.2)
                self.flush()
                step = 0
                continue
            if step < 2:
                step += 1
                continue
            try:
                reply = arcos.SyncReply.parse(payload[1:])
            except Exception as exc:  # construct: not three NUL-terminated strings
                raise ProtocolError(f"bad SYNC2 reply {payload.hex(' ')}: {exc}") from None
            return RobotIdentity(str(reply.name), str(reply.type), str(reply.subtype))
        raise TimeoutError(
            f"{self.transport.url}: no robot answering the ARCOS handshake "
            f"({tried} SYNC packets in {timeout:g} s)"
        )

    def request_config(self, timeout: float) -> dict[str, Any] | None:
        """CONFIG, re-requested every 0.3 s, as ARIA does; None when the robot sends none."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.send(arcos.encode_command(Command.CONFIG, 1))
            resend = min(time.monotonic() + 0.3, deadline)
            while time.monotonic() < resend:
                payload = self.next_packet(0.05)
                if payload is not None and payload[0] == PacketType.CONFIG:
                    return dict(plain(arcos.CONFIG.parse(payload[1:])))
        return None


def _params_for(subtype: str, identity: RobotIdentity) -> RobotParams:
    params = arcos.ROBOT_PARAMS.get(subtype.lower())
    if params is None:
        known = ", ".join(sorted(arcos.ROBOT_PARAMS))
        raise UnknownRobotError(
            f"robot {identity.name!r} reports subtype {identity.subtype!r}, which robocli has "
            f"no parameters for (known: {known}); pass subtype=... or params=RobotParams(...)"
        )
    return params


def _clamp_int(value: int) -> int:
    return max(-0x7FFF, min(0x7FFF, value))


__all__ = ["LinkStats", "Pioneer", "PioneerState", "RobotIdentity"]
