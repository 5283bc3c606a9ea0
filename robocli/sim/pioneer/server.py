"""Built-in Pioneer simulator: a real ARCOS server on TCP and on a pseudo-terminal.

The same bytes a Pioneer's microcontroller (or MobileSim/AMRISim) puts on the wire, checked
against recorded ARIA <-> AMRISim traces (``tests/data/arcos``), with these deliberate
differences where the real robot behaves better than MobileSim:

* motors start **disabled** in every session until ``ENABLE 1`` (AROS >= 1.3 behaviour);
* the watchdog really stops the robot (decelerates to zero, keeps the session) after
  ``watchdog_s`` wall seconds without a valid packet, and obeys the next command;
* ``CLOSE`` ends the session but keeps the link usable, so a client can re-sync on it, and a
  TCP client disconnect frees the **same** port for the next client (no port hopping);
* the battery drains (its state of charge goes in the SIP with ``state_of_charge=True``; by
  default 0, as MobileSim/AMRISim, so that the vendor SDK shows volts); IO, encoder and
  battery packets exist;
* a laser enable shows from the next SIP (AMRISim: the third), MobileSim's commands 35-38
  are laser commands only on a robot with a laser (``laser=None`` keeps ADSEL & co.);
* CONFIG's tops are the robot's real ones (p3dx: 2200 mm/s, not AMRISim's 9999) and its
  maxima stay within them, as does SETV (AMRISim: TransVelMax 3000); SIMSTAT's GPS fix has
  no AMRISim bias, and the ranges are exact to the walls (Stage's raster reads ~2 cm short).

As MobileSim/AMRISim it reports itself as a simulator (CONFIG serial ``SIM``) and serves the
simulated laser (0x60/0x61 after every SIP), SIMSTAT (0x62) with the true pose and, with a
georeference, a GPS fix, SIM_SET_POSE and SIM_RESET (``robocli.sim.pioneer.simext``); SETO shows
in the second SIP after it, as in AMRISim.

The simulator glues three parts: the robot model (``robocli.sim.pioneer.model``: physics,
odometry, collisions, battery, sonar in a ``World``), the ARCOS firmware
(``robocli.sim.pioneer.session``: handshake, commands, packets, watchdog; no sockets) and the
shared serving layer (``robocli.serving.server``: a thread per TCP link replying inline, the pty,
one client per robot, a second one refused with ``robocli-refused: robot busy: ...``).

Threads: one ticker (physics + SIPs on absolute deadlines ``t0 + k * period``) pushing through
the session's link, a listener and one thread per link. All robot and protocol state is
guarded by the controller's lock. Nothing is global: simulators are independent.
"""

from __future__ import annotations

import collections
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from robocli.errors import InvalidArgument
from robocli.robots.pioneer import ROBOT_PARAMS
from robocli.serving.server import SIM_HANDSHAKE_S, Server, poll_until
from robocli.sim.front import PoseTruth, RobotFront
from robocli.sim.laser import LMS200, LaserSpec
from robocli.sim.pioneer.model import PioneerModel, Pose
from robocli.sim.pioneer.packets import sonar_batch
from robocli.sim.pioneer.session import PRE_SYNC, ArcosController
from robocli.sim.pioneer.simext import Georef
from robocli.sim.world import World

__all__ = ["PioneerSim", "SimState", "serve_many", "sonar_batch"]

SEND_TIMEOUT_S = 1.0  #: a TCP client that does not read for this long is dropped
BYTE_TIMEOUT_S = 0.1  #: a partial frame with no new byte for this long is abandoned (as ARCOS)
MAX_FRAME = 258  #: largest ARCOS frame (count byte 255)


@dataclass(frozen=True)
class SimState(PoseTruth):
    """A copy of the simulator's truth at one instant (all SI unless the name says otherwise).

    ``x, y, th``: true pose in the world (m, rad). ``odom_*``: the robot's own odometry, the
    integral of its wheel motion since the session start or SETO (m, rad); ``odom_raw`` is the
    SIP's (x, y, th) counters. ``*_set``: the velocity the controller steers toward (m/s,
    rad/s). ``bumpers``: the bumper bits of STALL_AND_BUMPERS (bits 1-7 rear, 9-15 front).
    ``sync_state``: handshake progress of the link that last sent a packet (0 pre-sync,
    1..3 after SYNC0..SYNC2, 4 in session). ``commands``: names of every command received
    (pre-session 0/1/2 count as SYNC0/1/2). ``sim_time``: simulated seconds.
    """

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
    laser_mode: int = 0  #: 0 off, 1 plain scans (0x60), 2 extended scans (0x61)
    laser_scans: int = 0  #: complete scans sent
    laser_ranges: tuple[float, ...] = ()  #: the last scan's ranges (m; inf: no return)
    simstat_mode: int = 0  #: 0 off, 2 a SIMSTAT before every SIP
    laser_enabled_at_sip: int = 0  #: ``sips_sent`` when the laser was last switched on
    #: SIP cycles skipped because the simulator ran more than a cycle late (an overloaded
    #: machine); a real controller skips them too rather than send a burst
    cycles_skipped: int = 0
    #: client links connected now (a closed client's link goes once its thread sees the end)
    clients: int = 0


class PioneerSim(RobotFront):
    """An ARCOS robot: the protocol server, a physics model and a world.

    ``sip_ms``: SIP cycle (ms of simulated time). ``time_scale``: simulated seconds per wall
    second (physics and SIPs run that much faster). ``watchdog_s``: **wall** seconds without a
    valid packet after which a session's robot is stopped (0 disables). ``start_pose``: m, m,
    rad (default: the world's start). ``odom_noise``: relative standard deviation of odometry
    per step (0 = odometry equals the true motion), drawn from ``seed``. ``laser``: the
    simulated laser (SICK LMS200 by default; None: no laser). ``georef``: latitude, longitude
    (deg) and altitude (m) of the world origin, for SIMSTAT's GPS fix (None: no georeference).
    ``reflectors``: wall segments ``(x1, y1, x2, y2)`` (m) covered with reflective tape: the
    laser reports reflectance 32 on them, as MobileSim for a map's ``Reflector`` lines.
    ``state_of_charge``: report the battery's state of charge (percent) in the SIP; False
    (the default) sends 0 as MobileSim/AMRISim do, and clients show the voltage.
    ``handshake_s``: wall seconds a TCP connection has to complete SYNC0..SYNC2 before it is
    closed (the robot has one place: an idle connection must not hold it).
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
        laser: LaserSpec | None = LMS200,
        georef: Georef | None = None,
        reflectors: Sequence[Sequence[float]] = (),
        state_of_charge: bool = False,
        handshake_s: float = SIM_HANDSHAKE_S,
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
        if not handshake_s > 0:
            raise ValueError("handshake_s must be > 0")
        self.handshake_s = handshake_s
        period = sip_ms / 1000.0 / time_scale
        start = start_pose if start_pose is not None else self.world.start
        self._model = PioneerModel(self.params, self.world, start, odom_noise, seed)
        self._ctl = ArcosController(
            self._model, name=name, subtype=subtype, sip_ms=sip_ms, period=period,
            watchdog_s=watchdog_s, laser=laser, georef=georef, seed=seed, reflectors=reflectors,
            state_of_charge=state_of_charge,
        )  # fmt: skip
        super().__init__(period, "pioneer-sim-ticker")

    # ---------------------------------------------------------------- public API

    def serve_tcp(self, host: str = "127.0.0.1", port: int = 8101) -> str:
        """Listen on ``host:port`` (0 = an ephemeral port) and serve one client at a time (a
        second one is refused with a reason). Returns ``tcp://host:port`` with the real port."""
        return self._serve("tcp", lambda s: s.serve_tcp(host, port))

    def serve_pty(self) -> str:
        """Serve on a new pseudo-terminal (raw mode); returns the device a client opens."""
        return self._serve("pty", lambda s: s.serve_pty())

    def set_pose(self, x: float, y: float, th: float) -> None:
        """Teleport the true pose (m, m, rad); odometry is unchanged (like SIM_SET_POSE)."""
        with self._ctl.lock:
            self._model.teleport(x, y, th)

    def snapshot(self) -> SimState:
        """A consistent copy of the truth (thread-safe)."""
        stats = [s.stats() for s in self._serving()]
        bad = sum(s.bad_checksums for s in stats)
        dropped = sum(s.dropped_bytes for s in stats)
        # before the controller lock: a link ending holds its server's lock, then takes the
        # controller's (detach), so the other order would deadlock
        clients = sum(len(srv.links()) for srv in self._serving())
        with self._ctl.lock:
            return self._snapshot(bad, dropped, clients)

    def wait_until(self, predicate: Callable[[SimState], bool], timeout: float) -> SimState:
        """Poll snapshots until ``predicate`` holds; raises :class:`~robocli.errors.TimeoutError`
        after ``timeout`` wall seconds."""
        return poll_until(self.snapshot, predicate, timeout)

    # ---------------------------------------------------------------- internals

    def _new_server(self, kind: str) -> Server:
        return Server(
            self._ctl.attach, protocol="arcos", max_clients=1, max_frame=MAX_FRAME,
            byte_timeout=BYTE_TIMEOUT_S, send_timeout=SEND_TIMEOUT_S, name=f"pioneer-sim-{kind}",
            handshake_timeout=self.handshake_s,
        )  # fmt: skip

    def _tick(self, now: float) -> None:
        session, data = self._ctl.tick(now)
        if session is not None and data:
            session.link.send(data)

    def _snapshot(self, bad_checksums: int, dropped_bytes: int, clients: int) -> SimState:
        r, c = self._model, self._ctl
        left, right = r.wheel_speeds()
        last = c.last
        return SimState(
            x=r.x, y=r.y, th=r.th,
            odom_x=r.odom[0], odom_y=r.odom[1], odom_th=r.odom[2], odom_raw=c.odom_raw(),
            trans_vel=r.v, rot_vel=r.w, trans_vel_set=r.v_goal, rot_vel_set=r.w_goal,
            left_mm_s=left * 1000.0, right_mm_s=right * 1000.0,
            motors_enabled=r.motors, sonar_enabled=c.sonar_on, estop=r.estop,
            session_open=c.holder is not None,
            sync_state=last.sync_state if last is not None else PRE_SYNC,
            sessions=c.sessions, watchdog_trips=c.watchdog_trips,
            stalled=r.stall_bits != 0, bumpers=r.bumper_bits,
            battery_volts=r.volts, state_of_charge=r.state_of_charge,
            sonar=tuple(float(v) for v in r.sonar),
            commands=collections.Counter(c.commands),
            bad_checksums=bad_checksums, dropped_bytes=dropped_bytes,
            sim_time=r.sim_time, sips_sent=c.sips, last_say=c.last_say,
            digout=c.digout, encoder_ticks=r.encoder_ticks(),
            laser_mode=c.ext.laser_mode, laser_scans=c.ext.scans, laser_ranges=c.ext.last_scan,
            simstat_mode=c.ext.simstat_mode, laser_enabled_at_sip=c.ext.enabled_at_sip,
            cycles_skipped=self._ticker.skipped,
            clients=clients,
        )  # fmt: skip


def serve_many(
    n: int, *, host: str = "127.0.0.1", port: int = 8101, pty: bool = False,
    factory: Callable[..., PioneerSim] | None = None, **kw: Any,
) -> list[PioneerSim]:  # fmt: skip
    """``n`` independent robots on ``port``, ``port + 1``, ... (``port=0``: ephemeral ports),
    or each on its own pseudo-terminal with ``pty=True`` (``host``/``port`` unused). Keyword
    arguments go to :class:`PioneerSim` (or ``factory``, e.g. a
    :class:`~robocli.sim.pioneer.replay.PioneerReplay`). On failure the robots already
    started are closed."""
    if port and not pty and port + n - 1 > 65535:
        raise InvalidArgument(f"port {port} + {n} robots runs past port 65535")
    sims: list[PioneerSim] = []
    try:
        for i in range(n):
            sim = (factory or PioneerSim)(**kw)
            sims.append(sim)
            if pty:
                sim.serve_pty()
            else:
                sim.serve_tcp(host, port + i if port else 0)
    except BaseException:
        for sim in sims:
            sim.close()
        raise
    return sims
