"""Built-in Pioneer simulator: a real ARCOS server on TCP and on a pseudo-terminal.

The same bytes a Pioneer's microcontroller (or MobileSim/AMRISim) puts on the wire, checked
against recorded ARIA <-> AMRISim traces (``tests/data/arcos``), with these deliberate
differences where the real robot behaves better than MobileSim:

* motors start **disabled** in every session until ``ENABLE 1`` (AROS >= 1.3 behaviour);
* the watchdog really stops the robot (decelerates to zero, keeps the session) after
  ``watchdog_s`` wall seconds without a valid packet, and obeys the next command;
* ``CLOSE`` ends the session but keeps the link usable, so a client can re-sync on it, and a
  TCP client disconnect frees the **same** port for the next client (no port hopping);
* the battery drains and ``state_of_charge`` is reported; IO, encoder and battery packets exist.

Threads: one ticker (physics + SIPs on absolute deadlines ``t0 + k * period``) and one reader
per transport. All robot and protocol state is guarded by one lock per simulator; writes to a
link are serialised by the link's own lock. Nothing is global: simulators are independent.
"""

from __future__ import annotations

import collections
import errno
import logging
import math
import os
import selectors
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from types import TracebackType
from typing import Any

import numpy as np
from construct import ConstructError

from robocli.core import Framer
from robocli.errors import RobocliError, TimeoutError, TransportError
from robocli.protocols.arcos import (
    BUMPERS_FRONT_MASK,
    BUMPERS_REAR_MASK,
    CONFIG,
    FLAG_ESTOP,
    FLAG_MOTORS_ON,
    FLAG_SONAR_MASK,
    MAX_PAYLOAD,
    ROBOT_PARAMS,
    STALL_LEFT,
    STALL_RIGHT,
    Command,
    PacketType,
    RobotParams,
    decode_command,
    encode_server,
    encode_sip_body,
    frame,
    split_two_bytes,
)
from robocli.sim.world import World

__all__ = ["PioneerSim", "SimState", "serve_many"]

log = logging.getLogger("robocli.sim.pioneer")

Pose = tuple[float, float, float]

HANDSHAKE_TIMEOUT_S = 10.0  #: wall seconds of silence after which a half-open handshake resets
SEND_TIMEOUT_S = 1.0  #: a TCP client that does not read for this long is dropped
BYTE_TIMEOUT_S = 0.1  #: a partial frame with no new byte for this long is abandoned (as ARCOS)
MAX_FRAME = 258  #: largest ARCOS frame (count byte 255)
TICKS_PER_MM = 128  #: encoder ticks per mm of wheel travel (reported in CONFIG)
BATTERY_FULL_V = 13.0
BATTERY_EMPTY_V = 11.0
DRAIN_V_PER_M = 1.0e-4  #: battery drop per metre of wheel travel (both wheels summed)
DRAIN_V_PER_S = 1.0e-6  #: idle drain
ESTOP_DECEL = 2.0  #: m/s^2, ESTOP's "maximum deceleration"
ESTOP_ROT_DECEL = math.radians(500.0)
CONTACT_EPS = 0.005  #: m: a wall this close to the body presses its bumper
SONAR_CONE = math.radians(30.0)
SONAR_RAYS = 3
SONAR_MIN_RANGE = 0.1
NUM_BUMPERS = 5  #: per bumper ring (P3-DX: 5 front, 5 rear)

# sync_state values
PRE_SYNC, AFTER_SYNC0, AFTER_SYNC1, AFTER_SYNC2, IN_SESSION = 0, 1, 2, 3, 4


def _wrap(a: float) -> float:
    """Angle into [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def _clamp(v: float, lo: float, hi: float) -> float:
    return lo if v < lo else hi if v > hi else v


def _int16(v: float) -> int:
    return int(_clamp(round(v), -32768, 32767))


def _approach(cur: float, goal: float, accel: float, decel: float, dt: float) -> float:
    """Move ``cur`` toward ``goal``: ``accel`` when speeding up in the same direction."""
    speeding_up = abs(goal) > abs(cur) and (cur == 0.0 or (cur > 0) == (goal > 0))
    step = (accel if speeding_up else decel) * dt
    if abs(goal - cur) <= step:
        return goal
    return cur + math.copysign(step, goal - cur)


def sonar_batch(n_total: int, cursor: int, k_max: int) -> tuple[list[int], int]:
    """Indices of the sonars to report in one SIP (at most ``k_max``) and the next cursor:
    all of them when they fit, else the next ``k_max`` in rotation."""
    if n_total <= k_max:
        return list(range(n_total)), 0
    idx = [(cursor + i) % n_total for i in range(k_max)]
    return idx, (cursor + k_max) % n_total


# ============================================================================ state snapshot


@dataclass(frozen=True)
class SimState:
    """A copy of the simulator's truth at one instant (all SI unless the name says otherwise).

    ``x, y, th``: true pose in the world (m, rad). ``odom_*``: the robot's own odometry, the
    integral of its wheel motion since the session start or SETO (m, rad); ``odom_raw`` is the
    SIP's (x, y, th) counters. ``*_set``: the velocity the controller steers toward (m/s,
    rad/s). ``bumpers``: the bumper bits of STALL_AND_BUMPERS (bits 1-7 rear, 9-15 front).
    ``sync_state``: handshake progress of the link that last sent a packet (0 pre-sync,
    1..3 after SYNC0..SYNC2, 4 in session). ``commands``: names of every command received
    (pre-session 0/1/2 count as SYNC0/1/2). ``sim_time``: simulated seconds.
    """

    x: float
    y: float
    th: float
    odom_x: float
    odom_y: float
    odom_th: float
    odom_raw: tuple[int, int, int]
    trans_vel: float
    rot_vel: float
    trans_vel_set: float
    rot_vel_set: float
    left_mm_s: float
    right_mm_s: float
    motors_enabled: bool
    sonar_enabled: bool
    estop: bool
    session_open: bool
    sync_state: int
    sessions: int
    watchdog_trips: int
    stalled: bool
    bumpers: int
    battery_volts: float
    state_of_charge: float
    sonar: tuple[float, ...]
    commands: collections.Counter[str]
    bad_checksums: int
    dropped_bytes: int
    sim_time: float
    sips_sent: int
    last_say: tuple[tuple[int, int], ...]
    digout: int
    encoder_ticks: tuple[int, int]


# ============================================================================ physics


@dataclass
class _Limits:
    """Per-session operating parameters (MobileSim's defaults), SI units."""

    trans_vel_max: float = 3.0
    trans_accel: float = 0.3
    trans_decel: float = 0.3
    rot_vel_max: float = math.radians(150.0)
    rot_accel: float = math.radians(100.0)
    rot_decel: float = math.radians(100.0)


class _Robot:
    """Unicycle with acceleration limits, collision against the world, odometry, battery.

    Not thread-safe: the simulator holds its lock around every call.
    """

    def __init__(
        self, params: RobotParams, world: World, start: Pose, noise: float, seed: int
    ) -> None:
        self.params = params
        self.world = world
        self.start = start
        self.noise = noise
        self.rng = np.random.default_rng(seed)
        self.half_track = 1.0 / (params.diff_conv * 1000.0)  # m: w = (r - l) / (2 * half_track)
        self.sensors = np.array([(s.x, s.y, s.th) for s in params.sonar], dtype=np.float64)
        self.limits = _Limits()
        self.x, self.y, self.th = start
        self.odom = [0.0, 0.0, 0.0]
        self.v = self.w = 0.0
        self.v_goal = self.w_goal = 0.0
        self.trans_mode = "vel"  # "vel" | "move"
        self.rot_mode = "vel"  # "vel" | "head"
        self.v_set = self.w_set = 0.0
        self.move_left = 0.0
        self.head_set = 0.0
        self.motors = False
        self.estop = False
        self.bump_stall = 0
        self.stall_bits = 0
        self.bumper_bits = 0
        self.wheel_travel = [0.0, 0.0]
        self.battery_v = BATTERY_FULL_V
        self.battery_override: float | None = None
        self.sim_time = 0.0
        self.sonar = np.full(len(self.sensors), params.sonar_max_range)
        self.update_sonar()

    # ---------------------------------------------------------------- commands (SI)

    def halt(self) -> None:
        """Both set-points to zero (normal deceleration)."""
        self.trans_mode, self.rot_mode = "vel", "vel"
        self.v_set = self.w_set = 0.0

    def set_motors(self, on: bool) -> None:
        if on and self.motors:
            return  # ENABLE 1 while enabled changes nothing (and must not stop the robot)
        self.halt()
        self.motors = on
        self.estop = False
        if not on:
            self.v = self.w = 0.0

    def set_trans(self, v: float) -> None:
        self.trans_mode, self.v_set = "vel", v

    def set_rot(self, w: float) -> None:
        self.rot_mode, self.w_set = "vel", w

    def move(self, dist: float) -> None:
        self.trans_mode, self.move_left = "move", dist

    def head(self, th_odom: float) -> None:
        self.rot_mode, self.head_set = "head", _wrap(th_odom)

    def wheels(self, left: float, right: float) -> None:
        self.set_trans((left + right) / 2.0)
        self.set_rot((right - left) / (2.0 * self.half_track))

    def emergency_stop(self) -> None:
        self.halt()
        self.estop = self.v != 0.0 or self.w != 0.0

    def reset_odometry(self) -> None:
        self.odom = [0.0, 0.0, 0.0]
        if self.rot_mode == "head":
            self.head_set = 0.0

    def teleport(self, x: float, y: float, th: float) -> None:
        self.x, self.y, self.th = x, y, _wrap(th)
        self.update_sonar()

    def reset_session(self) -> None:
        """State at OPEN and after a session: stopped, motors off, defaults, odometry zero."""
        self.set_motors(False)
        self.limits = _Limits()
        self.bump_stall = 0
        self.reset_odometry()
        self.wheel_travel = [0.0, 0.0]

    # ---------------------------------------------------------------- readings

    @property
    def volts(self) -> float:
        return self.battery_v if self.battery_override is None else self.battery_override

    @property
    def state_of_charge(self) -> float:
        frac = (self.volts - BATTERY_EMPTY_V) / (BATTERY_FULL_V - BATTERY_EMPTY_V)
        return _clamp(100.0 * frac, 0.0, 100.0)

    def wheel_speeds(self) -> tuple[float, float]:
        """(left, right) m/s."""
        d = self.w * self.half_track
        return self.v - d, self.v + d

    def encoder_ticks(self) -> tuple[int, int]:
        def ticks(m: float) -> int:
            return ((round(m * 1000.0 * TICKS_PER_MM) + 2**31) % 2**32) - 2**31

        return ticks(self.wheel_travel[0]), ticks(self.wheel_travel[1])

    def update_sonar(self) -> None:
        self.sonar = self.world.sonar(
            (self.x, self.y, self.th),
            self.sensors,
            cone=SONAR_CONE,
            rays=SONAR_RAYS,
            min_range=SONAR_MIN_RANGE,
            max_range=self.params.sonar_max_range,
        )

    # ---------------------------------------------------------------- dynamics

    def step(self, dt: float) -> None:
        self.sim_time += dt
        if self.motors:
            self.v_goal, self.w_goal = self._trans_goal(dt), self._rot_goal(dt)
            lim = self.limits
            decel, rdecel = (
                (ESTOP_DECEL, ESTOP_ROT_DECEL) if self.estop else (lim.trans_decel, lim.rot_decel)
            )
            self.v = _approach(self.v, self.v_goal, lim.trans_accel, decel, dt)
            self.w = _approach(self.w, self.w_goal, lim.rot_accel, rdecel, dt)
            self.v = _clamp(self.v, -self.params.max_velocity, self.params.max_velocity)
            wmax = self.params.max_rot_velocity
            self.w = _clamp(self.w, -wmax, wmax)
        else:
            self.v_goal = self.w_goal = self.v = self.w = 0.0
        if self.estop and self.v == 0.0 and self.w == 0.0:
            self.estop = False
        self._integrate(dt)
        self.update_sonar()

    def _trans_goal(self, dt: float) -> float:
        vmax = min(self.limits.trans_vel_max, self.params.max_velocity)
        if self.trans_mode == "move":
            left = self.move_left
            if abs(left) < 0.0005:
                self.set_trans(0.0)
                return 0.0
            mag = min(vmax, math.sqrt(2.0 * self.limits.trans_decel * abs(left)), abs(left) / dt)
            return math.copysign(mag, left)
        return _clamp(self.v_set, -vmax, vmax)

    def _rot_goal(self, dt: float) -> float:
        wmax = min(self.limits.rot_vel_max, self.params.max_rot_velocity)
        if self.rot_mode == "head":
            err = _wrap(self.head_set - self.odom[2])
            if abs(err) < math.radians(0.05):
                return 0.0
            mag = min(wmax, math.sqrt(2.0 * self.limits.rot_decel * abs(err)), abs(err) / dt)
            return math.copysign(mag, err)
        return _clamp(self.w_set, -wmax, wmax)

    def _integrate(self, dt: float) -> None:
        ds, dth = self.v * dt, self.w * dt
        self.stall_bits = 0
        if ds != 0.0:
            frac = self._free_fraction(ds, dth)
            if frac < 1.0:
                ds, dth = ds * frac, dth * frac
                self._stall(front=self.v > 0)
        mid = self.th + dth / 2.0
        self.x += ds * math.cos(mid)
        self.y += ds * math.sin(mid)
        self.th = _wrap(self.th + dth)
        self._odometry(ds, dth)
        self.bumper_bits = self._contact_bumpers()
        travel = abs(ds - dth * self.half_track) + abs(ds + dth * self.half_track)
        self.battery_v = max(
            BATTERY_EMPTY_V - 1.0, self.battery_v - DRAIN_V_PER_M * travel - DRAIN_V_PER_S * dt
        )

    def _odometry(self, ds: float, dth: float) -> None:
        if self.noise > 0.0 and (ds or dth):
            ds *= 1.0 + self.noise * float(self.rng.standard_normal())
            dth *= 1.0 + self.noise * float(self.rng.standard_normal())
        ox, oy, oth = self.odom
        mid = oth + dth / 2.0
        self.odom = [ox + ds * math.cos(mid), oy + ds * math.sin(mid), _wrap(oth + dth)]
        self.wheel_travel[0] += ds - dth * self.half_track
        self.wheel_travel[1] += ds + dth * self.half_track
        if self.trans_mode == "move":
            self.move_left -= ds

    def _stall(self, *, front: bool) -> None:
        self.stall_bits = STALL_LEFT | STALL_RIGHT
        self.v = self.w = 0.0
        if self.bump_stall & (1 if front else 2):
            self.halt()

    def _ok(self, ds: float, dth: float, before: float) -> bool:
        mid = self.th + dth / 2.0
        d = self.world.clearance(self.x + ds * math.cos(mid), self.y + ds * math.sin(mid))
        return d >= self.params.radius or d >= before

    def _free_fraction(self, ds: float, dth: float) -> float:
        """Largest fraction of the step that keeps the body out of the walls (1.0 = all)."""
        before = self.world.clearance(self.x, self.y)
        if math.isinf(before):
            return 1.0
        n = max(1, math.ceil(abs(ds) / (self.params.radius / 2.0)))
        lo = 0.0
        for k in range(1, n + 1):
            hi = k / n
            if not self._ok(ds * hi, dth * hi, before):
                for _ in range(12):
                    mid = (lo + hi) / 2.0
                    lo, hi = (mid, hi) if self._ok(ds * mid, dth * mid, before) else (lo, mid)
                return lo
            lo = hi
        return 1.0

    def _contact_bumpers(self) -> int:
        d, px, py = self.world.nearest(self.x, self.y)
        if d > self.params.radius + CONTACT_EPS:
            return 0
        a = _wrap(math.atan2(py - self.y, px - self.x) - self.th)
        front = abs(a) <= math.pi / 2
        if not front:
            a = _wrap(a - math.pi)
        i = int(_clamp((math.pi / 2 - a) / (math.pi / NUM_BUMPERS), 0, NUM_BUMPERS - 1))
        bit = 1 << (i + 1)  # bumper 0 = leftmost seen from its ring's side
        return (bit << 8) & BUMPERS_FRONT_MASK if front else bit & BUMPERS_REAR_MASK


# ============================================================================ links


@dataclass
class _Link:
    """One byte stream to a client (a TCP connection or the pty) and its protocol state."""

    name: str
    writer: Callable[[bytes], None]
    framer: Framer = field(default_factory=lambda: Framer("arcos"))
    sync_state: int = PRE_SYNC
    last_rx: float = field(default_factory=time.monotonic)
    watchdog_tripped: bool = False
    sip_due: float = 0.0
    requests: dict[str, int] = field(default_factory=lambda: {"encoder": 0, "io": 0, "battery": 0})
    alive: bool = True
    bad_checksums: int = 0
    dropped_bytes: int = 0
    tail: bytearray = field(default_factory=bytearray)  #: the last MAX_FRAME bytes received
    last_bytes: float = 0.0  #: monotonic time of the last bytes received
    abandoned: int = 0  #: bytes skipped by the inter-byte timeout
    lock: threading.Lock = field(default_factory=threading.Lock)

    def send(self, data: bytes) -> None:
        """Write (thread-safe); a failed write marks the link dead for its reader to drop."""
        if not data or not self.alive:
            return
        with self.lock:
            try:
                self.writer(data)
            except OSError as exc:
                log.info("%s: write failed (%s); dropping the link", self.name, exc)
                self.alive = False


# ============================================================================ the simulator


class PioneerSim:
    """An ARCOS robot: the protocol server, a physics model and a world.

    ``sip_ms``: SIP cycle (ms of simulated time). ``time_scale``: simulated seconds per wall
    second (physics and SIPs run that much faster). ``watchdog_s``: **wall** seconds without a
    valid packet after which a session's robot is stopped (0 disables). ``start_pose``: m, m,
    rad (default: the world's start). ``odom_noise``: relative standard deviation of odometry
    per step (0 = odometry equals the true motion), drawn from ``seed``.
    """

    def __init__(
        self,
        subtype: str = "p3dx",
        *,
        name: str = "robocli-sim",
        sip_ms: float = 100.0,
        time_scale: float = 1.0,
        world: World | None = None,
        watchdog_s: float = 2.0,
        start_pose: Pose | None = None,
        seed: int = 0,
        odom_noise: float = 0.0,
    ) -> None:
        if subtype not in ROBOT_PARAMS:
            known = ", ".join(sorted(ROBOT_PARAMS))
            raise ValueError(f"unknown Pioneer subtype {subtype!r}; known: {known}")
        if not 1.0 <= sip_ms <= 255.0:
            raise ValueError("sip_ms must be within 1..255")
        if time_scale <= 0 or watchdog_s < 0:
            raise ValueError("time_scale must be > 0 and watchdog_s >= 0")
        self.subtype, self.name = subtype, name
        self.params = ROBOT_PARAMS[subtype]
        self.world = world if world is not None else World.default()
        self.sip_ms, self.time_scale, self.watchdog_s = sip_ms, time_scale, watchdog_s
        self._dt = sip_ms / 1000.0
        self._period = self._dt / time_scale
        start = start_pose if start_pose is not None else self.world.start
        self._robot = _Robot(self.params, self.world, start, odom_noise, seed)
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._links: list[_Link] = []
        self._session: _Link | None = None
        self._last_link: _Link | None = None
        self._closed = False
        self._url: str | None = None
        self._pty_path: str | None = None
        self._commands: collections.Counter[str] = collections.Counter()
        self._past_bad_checksums = self._past_dropped = 0
        self._sessions = self._watchdog_trips = self._sips = 0
        self._sonar_on = False
        self._sonar_cursor = 0
        self._digin, self._digout, self._anport = 0xFF, 0xFF, 0
        self._last_say: tuple[tuple[int, int], ...] = ()
        self._handlers = self._make_handlers()
        self._config_cache: tuple[tuple[Any, ...], bytes] | None = None
        head = ("x", "y", "th", "lvel", "rvel", "battery", "stall_bumpers", "control", "flags")
        empty: dict[str, Any] = {**dict.fromkeys(head, 0), "compass": 0, "sonar": ()}
        self._sip_fixed = len(encode_sip_body({**empty, **self._sip_tail()}))
        self._sonar_k_max = max(0, (MAX_PAYLOAD - self._sip_fixed) // 3)

    # ---------------------------------------------------------------- public API

    @property
    def url(self) -> str | None:
        """``tcp://host:port`` once :meth:`serve_tcp` ran."""
        return self._url

    @property
    def pty_path(self) -> str | None:
        """The pseudo-terminal device once :meth:`serve_pty` ran."""
        return self._pty_path

    def serve_tcp(self, host: str = "127.0.0.1", port: int = 8101) -> str:
        """Listen on ``host:port`` (0 = an ephemeral port) and serve one client at a time.
        Returns ``tcp://host:port`` with the real port."""
        self._check_open()
        if self._url is not None:
            raise TransportError(f"already serving on {self._url}")
        listener = _listen(host, port)
        real_port = listener.getsockname()[1]
        shown = f"[{host}]" if ":" in host else host
        self._url = f"tcp://{shown}:{real_port}"
        self._start_thread(f"pioneer-sim-tcp-{real_port}", self._tcp_loop, listener)
        self._start_ticker()
        log.info("%s (%s) listening on %s", self.name, self.subtype, self._url)
        return self._url

    def serve_pty(self) -> str:
        """Serve on a new pseudo-terminal (raw mode); returns the device a client opens."""
        self._check_open()
        if self._pty_path is not None:
            raise TransportError(f"already serving on {self._pty_path}")
        if not hasattr(os, "openpty"):
            raise TransportError("pseudo-terminals are not available on this platform")
        import tty

        master, slave = os.openpty()
        tty.setraw(slave)
        os.set_blocking(master, False)
        self._pty_path = os.ttyname(slave)
        self._start_thread("pioneer-sim-pty", self._pty_loop, master, slave)
        self._start_ticker()
        log.info("%s (%s) serving on %s", self.name, self.subtype, self._pty_path)
        return self._pty_path

    def close(self) -> None:
        """Stop every thread and close every socket/fd. Idempotent."""
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        for t in self._threads:
            if t is not threading.current_thread():
                t.join(timeout=5.0)
        with self._lock:
            for link in list(self._links):
                self._detach(link)

    def __enter__(self) -> PioneerSim:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def set_pose(self, x: float, y: float, th: float) -> None:
        """Teleport the true pose (m, m, rad); odometry is unchanged (like SIM_SET_POSE)."""
        with self._lock:
            self._robot.teleport(x, y, th)

    def snapshot(self) -> SimState:
        """A consistent copy of the truth (thread-safe)."""
        with self._lock:
            return self._snapshot()

    def wait_until(self, predicate: Callable[[SimState], bool], timeout: float) -> SimState:
        """Poll snapshots until ``predicate`` holds; raises :class:`~robocli.errors.TimeoutError`
        after ``timeout`` wall seconds."""
        deadline = time.monotonic() + timeout
        while True:
            state = self.snapshot()
            if predicate(state):
                return state
            if time.monotonic() >= deadline:
                raise TimeoutError(f"simulator condition not met within {timeout:g} s")
            time.sleep(min(0.005, max(0.0, deadline - time.monotonic())))

    # ---------------------------------------------------------------- snapshot

    def _snapshot(self) -> SimState:
        r = self._robot
        left, right = r.wheel_speeds()
        last = self._last_link
        return SimState(
            x=r.x, y=r.y, th=r.th,
            odom_x=r.odom[0], odom_y=r.odom[1], odom_th=r.odom[2], odom_raw=self._odom_raw(),
            trans_vel=r.v, rot_vel=r.w, trans_vel_set=r.v_goal, rot_vel_set=r.w_goal,
            left_mm_s=left * 1000.0, right_mm_s=right * 1000.0,
            motors_enabled=r.motors, sonar_enabled=self._sonar_on, estop=r.estop,
            session_open=self._session is not None,
            sync_state=last.sync_state if last is not None else PRE_SYNC,
            sessions=self._sessions, watchdog_trips=self._watchdog_trips,
            stalled=r.stall_bits != 0, bumpers=r.bumper_bits,
            battery_volts=r.volts, state_of_charge=r.state_of_charge,
            sonar=tuple(float(v) for v in r.sonar),
            commands=collections.Counter(self._commands),
            bad_checksums=self._past_bad_checksums + sum(k.bad_checksums for k in self._links),
            dropped_bytes=self._past_dropped + sum(k.dropped_bytes for k in self._links),
            sim_time=r.sim_time, sips_sent=self._sips, last_say=self._last_say,
            digout=self._digout, encoder_ticks=r.encoder_ticks(),
        )  # fmt: skip

    # ---------------------------------------------------------------- threads

    def _check_open(self) -> None:
        if self._closed:
            raise TransportError("simulator is closed")

    def _start_thread(self, name: str, target: Callable[..., None], *args: Any) -> None:
        t = threading.Thread(target=target, args=args, name=name, daemon=True)
        self._threads.append(t)
        t.start()

    def _start_ticker(self) -> None:
        if not any(t.name == "pioneer-sim-ticker" for t in self._threads):
            self._start_thread("pioneer-sim-ticker", self._tick_loop)

    def _tick_loop(self) -> None:
        period = self._period
        t0 = time.monotonic()
        k = 0
        while not self._stop.is_set():
            k += 1
            delay = t0 + k * period - time.monotonic()
            if delay > 0:
                if self._stop.wait(delay):
                    break
            elif -delay > period:
                skipped = int(-delay / period)
                log.debug("ticker %.1f ms late; skipping %d ticks", -delay * 1e3, skipped)
                k += skipped
            try:
                self._tick(time.monotonic())
            except Exception:  # noqa: BLE001 - the ticker must survive one bad tick
                log.exception("simulator tick failed")

    def _tick(self, now: float) -> None:
        with self._lock:
            self._robot.step(self._dt)
            self._housekeeping(now)
            link = self._session
            data = self._session_packets(link, now) if link is not None else b""
        if link is not None and data:
            link.send(data)

    def _housekeeping(self, now: float) -> None:
        link = self._session
        if (
            link is not None
            and self.watchdog_s > 0
            and not link.watchdog_tripped
            and now - link.last_rx > self.watchdog_s
        ):
            link.watchdog_tripped = True
            self._watchdog_trips += 1
            self._robot.halt()
            log.warning(
                "%s: no valid packet for %.0f ms (watchdog %.0f ms): stopping the robot",
                link.name, (now - link.last_rx) * 1e3, self.watchdog_s * 1e3,
            )  # fmt: skip
        for other in self._links:
            in_handshake = AFTER_SYNC0 <= other.sync_state <= AFTER_SYNC2
            if in_handshake and now - other.last_rx > HANDSHAKE_TIMEOUT_S:
                log.info("%s: handshake abandoned; back to pre-sync", other.name)
                other.sync_state = PRE_SYNC

    # ---------------------------------------------------------------- links

    def _attach(self, link: _Link) -> None:
        with self._lock:
            self._links.append(link)
        log.info("%s: client connected", link.name)

    def _detach(self, link: _Link) -> None:
        with self._lock:
            if link not in self._links:
                return
            self._end_session(link, "link closed")
            self._links.remove(link)
            self._past_bad_checksums += link.bad_checksums
            self._past_dropped += link.dropped_bytes
            if self._last_link is link:
                self._last_link = None
            link.alive = False
        log.info("%s: client gone", link.name)

    def _on_bytes(self, link: _Link, data: bytes) -> None:
        link.last_bytes = time.monotonic()
        link.tail += data
        del link.tail[:-MAX_FRAME]
        frames = link.framer.feed(data)
        stats = link.framer.stats
        replies: list[bytes] = []
        with self._lock:
            link.bad_checksums = stats.bad_checksums
            link.dropped_bytes = stats.dropped_bytes + link.abandoned
            now = time.monotonic()
            for raw in frames:
                reply = self._handle(link, raw[3:-2], now)
                if reply:
                    replies.append(reply)
        if replies:
            link.send(b"".join(replies))

    def _check_byte_timeout(self, link: _Link) -> None:
        """A frame header whose body never comes (e.g. garbage ``FA FB FF``) must not hold
        the commands behind it hostage: after BYTE_TIMEOUT_S of silence drop its first byte
        and rescan the rest (ARCOS and ARIA give up on a partial packet after 100 ms)."""
        pending = link.framer.pending
        if not pending or time.monotonic() - link.last_bytes < BYTE_TIMEOUT_S:
            return
        stale = bytes(link.tail[-pending:])
        link.framer.reset()
        link.tail.clear()
        link.abandoned += 1
        log.debug("%s: partial frame abandoned: %s", link.name, stale[:8].hex(" "))
        self._on_bytes(link, stale[1:])

    def _tcp_loop(self, listener: socket.socket) -> None:
        sel = selectors.DefaultSelector()
        sel.register(listener, selectors.EVENT_READ)
        client: tuple[socket.socket, _Link] | None = None
        try:
            while not self._stop.is_set():
                for key, _ in sel.select(timeout=0.05):
                    if key.fileobj is listener:
                        client = self._tcp_accept(listener, sel, client)
                    elif client is not None and not self._tcp_read(*client):
                        self._tcp_drop(sel, client)
                        client = None
                if client is not None and not client[1].alive:
                    self._tcp_drop(sel, client)
                    client = None
                if client is not None:
                    self._check_byte_timeout(client[1])
        finally:
            if client is not None:
                self._tcp_drop(sel, client)
            sel.close()
            listener.close()

    def _tcp_accept(
        self,
        listener: socket.socket,
        sel: selectors.BaseSelector,
        client: tuple[socket.socket, _Link] | None,
    ) -> tuple[socket.socket, _Link] | None:
        try:
            sock, addr = listener.accept()
        except OSError:
            return client
        peer = f"tcp {addr[0]}:{addr[1]}"
        if client is not None:
            log.warning("%s refused: %s already holds this robot", peer, client[1].name)
            sock.close()
            return client
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.settimeout(SEND_TIMEOUT_S)
        link = _Link(peer, sock.sendall)
        self._attach(link)
        sel.register(sock, selectors.EVENT_READ)
        return sock, link

    def _tcp_read(self, sock: socket.socket, link: _Link) -> bool:
        try:
            data = sock.recv(4096)
        except OSError:
            return False
        if not data:
            return False
        self._on_bytes(link, data)
        return True

    def _tcp_drop(self, sel: selectors.BaseSelector, client: tuple[socket.socket, _Link]) -> None:
        sock, link = client
        sel.unregister(sock)
        self._detach(link)
        sock.close()

    def _pty_loop(self, master: int, slave: int) -> None:
        link = _Link(f"pty {self._pty_path}", lambda data: _write_pty(master, data))
        self._attach(link)
        sel = selectors.DefaultSelector()
        sel.register(master, selectors.EVENT_READ)
        try:
            while not self._stop.is_set():
                if not sel.select(timeout=0.05):
                    self._check_byte_timeout(link)
                    continue
                try:
                    data = os.read(master, 4096)
                except BlockingIOError:
                    continue
                except OSError:  # EIO: no process holds the slave end right now
                    self._stop.wait(0.05)
                    continue
                if data:
                    self._on_bytes(link, data)
        finally:
            sel.close()
            self._detach(link)
            os.close(master)
            os.close(slave)

    # ---------------------------------------------------------------- protocol

    def _handle(self, link: _Link, payload: bytes, now: float) -> bytes | None:
        """One valid client packet (type + args) -> the immediate reply, if any."""
        link.last_rx = now
        link.watchdog_tripped = False
        self._last_link = link
        try:
            cmd = decode_command(payload)
        except (ConstructError, RobocliError, ValueError) as exc:
            log.debug("%s: undecodable command %s (%s)", link.name, payload.hex(" "), exc)
            return None
        if link.sync_state == IN_SESSION:
            self._commands[cmd.name] += 1
            handler = self._handlers.get(cmd.command)
            if handler is None:
                log.debug("%s: ignoring command %s", link.name, cmd.name)
                return None
            return handler(link, cmd.arg)
        return self._pre_session(link, cmd.command, cmd.arg)

    def _pre_session(self, link: _Link, c: int, arg: object) -> bytes | None:
        state = link.sync_state
        if c == 0:
            self._commands["SYNC0"] += 1
            link.sync_state = AFTER_SYNC0
            return frame(b"\x00")
        if c == 1 and state == AFTER_SYNC0:
            self._commands["SYNC1"] += 1
            link.sync_state = AFTER_SYNC1
            return frame(b"\x01")
        if c == 2 and state == AFTER_SYNC1:
            self._commands["SYNC2"] += 1
            link.sync_state = AFTER_SYNC2
            return encode_server(
                PacketType.SYNC2, {"name": self.name, "type": "Pioneer", "subtype": self.subtype}
            )
        if c == 1 and state == AFTER_SYNC2:
            self._commands["OPEN"] += 1
            self._open(link)
            return None
        if c in (1, 2):
            self._commands[("OPEN", "CLOSE")[c - 1] if arg is not None else f"SYNC{c}"] += 1
            log.debug("%s: out-of-order sync %d in state %d; restarting", link.name, c, state)
            link.sync_state = PRE_SYNC
        else:
            self._commands[_command_name(c)] += 1
            log.debug("%s: command %s before OPEN ignored", link.name, _command_name(c))
        return None

    def _open(self, link: _Link) -> None:
        holder = self._session
        if holder is not None and holder is not link:
            log.warning("%s: OPEN refused, %s holds the session", link.name, holder.name)
            link.sync_state = PRE_SYNC
            return
        self._session = link
        link.sync_state = IN_SESSION
        link.requests = dict.fromkeys(link.requests, 0)
        link.sip_due = time.monotonic() + self._period / 2.0  # first SIP ~ one period after OPEN
        self._sessions += 1
        self._robot.reset_session()
        self._sonar_on, self._sonar_cursor = True, 0
        log.info("%s: session %d open", link.name, self._sessions)

    def _end_session(self, link: _Link, why: str) -> None:
        link.sync_state = PRE_SYNC
        if self._session is not link:
            return
        self._session = None
        self._robot.reset_session()
        self._sonar_on = False
        log.info("%s: session ended (%s)", link.name, why)

    def _session_packets(self, link: _Link, now: float) -> bytes:
        if now < link.sip_due:
            return b""
        packets = [self._sip()]
        self._sips += 1
        for kind, build in (
            ("encoder", self._encoder_packet),
            ("io", self._io_packet),
            ("battery", self._battery_packet),
        ):
            mode = link.requests[kind]
            if mode:
                packets.append(build())
                if mode == 1:
                    link.requests[kind] = 0
        return b"".join(packets)

    # ---------------------------------------------------------------- server packets

    def _odom_raw(self) -> tuple[int, int, int]:
        p, (ox, oy, oth) = self.params, self._robot.odom
        x = round(ox * 1000.0 / p.dist_conv) & 0x7FFF
        y = round(oy * 1000.0 / p.dist_conv) & 0x7FFF
        th = (round(oth / p.angle_conv) + 2048) % 4096 - 2048
        return x, y, th

    def _sip_tail(self) -> dict[str, Any]:
        r = self._robot
        volts = round(r.volts * 10.0)
        return {
            "io": {"grip_state": 0, "anport": self._anport, "analog": 0,
                   "digin": self._digin, "digout": self._digout},
            "battery_x10": int(_clamp(volts, 0, 65535)), "charge_state": 0,
            "rotvel": _int16(math.degrees(r.w) * 10.0), "fault_flags": 0, "latvel": 0,
            "temperature": -127, "state_of_charge": round(r.state_of_charge),
        }  # fmt: skip

    def _sip(self) -> bytes:
        r, p = self._robot, self.params
        x, y, th = self._odom_raw()
        left, right = r.wheel_speeds()
        flags = (FLAG_MOTORS_ON if r.motors else 0) | (FLAG_ESTOP if r.estop else 0)
        sonar: list[tuple[int, int]] = []
        if self._sonar_on:
            flags |= FLAG_SONAR_MASK
            idx, self._sonar_cursor = sonar_batch(
                len(r.sonar), self._sonar_cursor, self._sonar_k_max
            )
            conv = 1000.0 / p.range_conv
            sonar = [(i, int(_clamp(round(r.sonar[i] * conv), 0, 65535))) for i in idx]
        body = {
            "x": x, "y": y, "th": th,
            "lvel": _int16(left * 1000.0 / p.vel_conv), "rvel": _int16(right * 1000.0 / p.vel_conv),
            "battery": int(_clamp(round(r.volts * 10.0), 0, 255)),
            "stall_bumpers": r.stall_bits | r.bumper_bits, "control": 0, "flags": flags,
            "compass": 0, "sonar": sonar, **self._sip_tail(),
        }  # fmt: skip
        return frame(bytes((PacketType.SIP,)) + encode_sip_body(body))

    def _config_packet(self) -> bytes:
        lim, p = self._robot.limits, self.params
        deg = math.degrees
        body: dict[str, Any] = {name: 0 for name in _CONFIG_FIELDS}
        body.update(
            robot_type="Pioneer", subtype=self.subtype, serial="SIM", name=self.name,
            firmware="robocli", rotvel_top=round(deg(p.max_rot_velocity)),
            transvel_top=round(p.max_velocity * 1000), rotacc_top=500, transacc_top=2000,
            pwm_max=400, sip_cycle=int(round(self.sip_ms)), front_sonar=1,
            rear_sonar=1 if len(p.sonar) > 8 else 0,
            watchdog=min(65535, round(self.watchdog_s * 1000)),
            rotvel_max=round(deg(lim.rot_vel_max)), transvel_max=round(lim.trans_vel_max * 1000),
            rot_accel=round(deg(lim.rot_accel)), rot_decel=round(deg(lim.rot_decel)),
            trans_accel=round(lim.trans_accel * 1000), trans_decel=round(lim.trans_decel * 1000),
            front_bumps=NUM_BUMPERS, rear_bumps=NUM_BUMPERS, reset_baud=2,
            ticks_mm=TICKS_PER_MM, latvel_top=0, latacc_top=0,
        )  # fmt: skip
        body.update(dict.fromkeys(_CONFIG_OPTIONAL))
        key = tuple(body.values())
        if self._config_cache is None or self._config_cache[0] != key:
            # construct takes ~0.3 ms to build it: rebuild only when a setting changed
            self._config_cache = (key, encode_server(PacketType.CONFIG, body))
        return self._config_cache[1]

    def _encoder_packet(self) -> bytes:
        left, right = self._robot.encoder_ticks()
        return encode_server(PacketType.ENCODER, {"left": left, "right": right})

    def _io_packet(self) -> bytes:
        bumps = self._robot.bumper_bits
        digin = [self._digin, (bumps >> 8) & 0xFF, bumps & 0xFF, 0]
        return encode_server(
            PacketType.IO, {"digin": digin, "digout": [self._digout], "analog": [0] * 8}
        )

    def _battery_packet(self) -> bytes:
        soc = round(self._robot.state_of_charge)
        data = bytes((0, 0, 0, soc, soc))
        return encode_server(
            PacketType.BATTERY, {"count": 1, "bytes_per_battery": len(data), "data": data}
        )

    # ---------------------------------------------------------------- in-session commands

    def _make_handlers(self) -> dict[int, Callable[[_Link, Any], bytes | None]]:
        return {
            Command.PULSE: lambda link, arg: None,
            Command.OPEN: lambda link, arg: None,
            Command.CLOSE: self._cmd_close,
            Command.ENABLE: self._cmd_enable,
            Command.SETA: self._cmd_seta,
            Command.SETV: self._cmd_setv,
            Command.SETO: lambda link, arg: self._robot.reset_odometry(),
            Command.MOVE: self._motion(lambda a: self._robot.move(a / 1000.0)),
            Command.ROTATE: self._motion(lambda a: self._robot.set_rot(math.radians(a))),
            Command.SETRV: self._cmd_setrv,
            Command.VEL: self._motion(lambda a: self._robot.set_trans(a / 1000.0)),
            Command.HEAD: self._motion(lambda a: self._robot.head(math.radians(a))),
            Command.DHEAD: self._motion(self._dhead),
            Command.SAY: self._cmd_say,
            Command.CONFIG: lambda link, arg: self._config_packet(),
            Command.ENCODER: self._request("encoder"),
            Command.RVEL: self._motion(lambda a: self._robot.set_rot(math.radians(a))),
            Command.DCHEAD: self._motion(self._dchead),
            Command.SETRA: self._cmd_setra,
            Command.SONAR: self._cmd_sonar,
            Command.STOP: lambda link, arg: self._robot.halt(),
            Command.DIGOUT: self._cmd_digout,
            Command.VEL2: self._motion(self._vel2),
            Command.ADSEL: self._cmd_adsel,
            Command.IOREQUEST: self._request("io"),
            Command.BUMPSTALL: self._cmd_bumpstall,
            Command.ESTOP: lambda link, arg: self._robot.emergency_stop(),
            Command.BATTERYINFO: self._request("battery"),
            Command.SIM_SET_POSE: self._cmd_sim_set_pose,
            Command.SIM_RESET: self._cmd_sim_reset,
            Command.BATTEST: self._cmd_battest,
        }

    def _motion(self, apply: Callable[[int], None]) -> Callable[[_Link, Any], None]:
        """A motion command taking an int: ignored (logged) while the motors are disabled."""

        def handler(link: _Link, arg: Any) -> None:
            if not isinstance(arg, int):
                log.debug("%s: motion command without an int argument ignored", link.name)
            elif not self._robot.motors:
                log.debug("%s: motors disabled; motion command ignored", link.name)
            else:
                apply(arg)

        return handler

    def _request(self, kind: str) -> Callable[[_Link, Any], None]:
        def handler(link: _Link, arg: Any) -> None:
            link.requests[kind] = int(_clamp(_int_arg(arg, 1), 0, 2))

        return handler

    def _cmd_close(self, link: _Link, arg: Any) -> None:
        self._end_session(link, "CLOSE")

    def _cmd_enable(self, link: _Link, arg: Any) -> None:
        self._robot.set_motors(_int_arg(arg) != 0)

    def _cmd_seta(self, link: _Link, arg: Any) -> None:
        a = _int_arg(arg) / 1000.0
        if a > 0:
            self._robot.limits.trans_accel = a
        elif a < 0:
            self._robot.limits.trans_decel = -a

    def _cmd_setra(self, link: _Link, arg: Any) -> None:
        a = math.radians(_int_arg(arg))
        if a > 0:
            self._robot.limits.rot_accel = a
        elif a < 0:
            self._robot.limits.rot_decel = -a

    def _cmd_setv(self, link: _Link, arg: Any) -> None:
        self._robot.limits.trans_vel_max = abs(_int_arg(arg)) / 1000.0

    def _cmd_setrv(self, link: _Link, arg: Any) -> None:
        self._robot.limits.rot_vel_max = math.radians(abs(_int_arg(arg)))

    def _dhead(self, deg: int) -> None:
        self._robot.head(self._robot.odom[2] + math.radians(deg))

    def _dchead(self, deg: int) -> None:
        r = self._robot
        base = r.head_set if r.rot_mode == "head" else r.odom[2]
        r.head(base + math.radians(deg))

    def _vel2(self, arg: int) -> None:
        left, right = split_two_bytes(arg)
        div = self.params.vel2_divisor / 1000.0
        self._robot.wheels(left * div, right * div)

    def _cmd_say(self, link: _Link, arg: Any) -> None:
        if isinstance(arg, bytes):
            pairs = zip(arg[0::2], arg[1::2], strict=False)
            self._last_say = tuple((d * 20, tone) for d, tone in pairs)

    def _cmd_sonar(self, link: _Link, arg: Any) -> None:
        self._sonar_on = _int_arg(arg) != 0

    def _cmd_digout(self, link: _Link, arg: Any) -> None:
        mask, values = (b & 0xFF for b in split_two_bytes(_int_arg(arg)))
        self._digout = (self._digout & ~mask | values & mask) & 0xFF

    def _cmd_adsel(self, link: _Link, arg: Any) -> None:
        self._anport = _int_arg(arg) & 0xFF

    def _cmd_bumpstall(self, link: _Link, arg: Any) -> None:
        self._robot.bump_stall = _int_arg(arg) & 3

    def _cmd_battest(self, link: _Link, arg: Any) -> None:
        dv = _int_arg(arg)
        self._robot.battery_override = dv / 10.0 if dv > 0 else None

    def _cmd_sim_set_pose(self, link: _Link, arg: Any) -> None:
        if isinstance(arg, tuple):
            x, y, th = arg
            self._robot.teleport(x / 1000.0, y / 1000.0, math.radians(th))

    def _cmd_sim_reset(self, link: _Link, arg: Any) -> None:
        self._robot.teleport(*self._robot.start)
        self._robot.reset_odometry()


# ============================================================================ helpers

_CONFIG_FIELDS = [str(sc.name) for sc in CONFIG.subcons]
_CONFIG_OPTIONAL = _CONFIG_FIELDS[_CONFIG_FIELDS.index("powerbot_charge_threshold") + 1 :]


def _int_arg(arg: Any, default: int = 0) -> int:
    return arg if isinstance(arg, int) else default


def _command_name(c: int) -> str:
    try:
        return Command(c).name
    except ValueError:
        return f"CMD_{c}"


def _write_pty(fd: int, data: bytes) -> None:
    """Write to the pty master; what the line cannot take now is dropped, as on a serial
    line with nobody listening."""
    view = memoryview(data)
    while view:
        try:
            n = os.write(fd, view)
        except BlockingIOError:
            log.debug("pty full: dropped %d bytes", len(view))
            return
        view = view[n:]


def _listen(host: str, port: int) -> socket.socket:
    try:
        family, kind, proto, _, addr = socket.getaddrinfo(
            host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE
        )[0]
    except socket.gaierror as exc:
        raise TransportError(f"cannot listen on {host}:{port}: {exc.strerror}") from exc
    sock = socket.socket(family, kind, proto)
    try:
        if os.name == "nt":
            sock.setsockopt(socket.SOL_SOCKET, getattr(socket, "SO_EXCLUSIVEADDRUSE", 0), 1)
        else:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind(addr)
        sock.listen(4)
    except OSError as exc:
        sock.close()
        if exc.errno in (errno.EADDRINUSE, getattr(errno, "WSAEADDRINUSE", -1)):
            raise TransportError(f"port {port} is in use: is another simulator running?") from exc
        raise TransportError(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from exc
    return sock


def serve_many(n: int, *, host: str = "127.0.0.1", port: int = 8101, **kw: Any) -> list[PioneerSim]:
    """``n`` independent robots on ``port``, ``port + 1``, ... (``port=0``: ephemeral ports).
    Keyword arguments go to :class:`PioneerSim`. On failure the robots already started are
    closed."""
    sims: list[PioneerSim] = []
    try:
        for i in range(n):
            sim = PioneerSim(**kw)
            sims.append(sim)
            sim.serve_tcp(host, port + i if port else 0)
    except BaseException:
        for sim in sims:
            sim.close()
        raise
    return sims
