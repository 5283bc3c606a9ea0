"""Built-in iRobot Create 2 simulator: the Open Interface on a pseudo-terminal and on TCP.

The simulator glues three parts, as the Pioneer's does: the body
(:mod:`robocli.sim.create.model`: the Pioneer's physics and world with the Create's geometry,
bumper, wheel drops, odometry, battery), the OI firmware (:mod:`robocli.sim.create.session`:
modes, commands, sensors, the stream) and the shared serving layer
(:mod:`robocli.serving.server`: a thread per link replying inline, the pty, one client at a
time, a second one refused with ``robocli-refused: robot busy: ...``). Commands are framed by
:class:`~robocli.protocols.create_oi.CommandFramer`: garbage is dropped and counted, a command
cut short for ``byte_timeout`` is abandoned (its first byte dropped, the rest rescanned).

Threads: one ticker (physics, safety, the stream every 15 ms of robot time, on absolute
deadlines), a listener and one thread per link. All robot and protocol state is guarded by the
controller's lock. Nothing is global.
"""

from __future__ import annotations

import collections
from collections.abc import Callable
from dataclasses import dataclass

from robocli.protocols.create_oi import MAX_COMMAND, CommandFramer
from robocli.serving.server import Server, poll_until
from robocli.sim.create.model import DROP_LEFT, DROP_RIGHT, CreateBody
from robocli.sim.create.session import CreateController
from robocli.sim.front import PoseTruth, RobotFront
from robocli.sim.pioneer.model import Pose
from robocli.sim.world import World

__all__ = ["STREAM_PERIOD_S", "CreateSim", "CreateSimState"]

STREAM_PERIOD_S = 0.015  #: the OI's stream period, and the physics step (robot seconds)
SEND_TIMEOUT_S = 1.0  #: a TCP client that does not read for this long is dropped
BYTE_TIMEOUT_S = 0.2  #: a command cut short for this long (wall s) is abandoned


@dataclass(frozen=True)
class CreateSimState(PoseTruth):
    """A copy of the simulator's truth at one instant (SI unless the name says otherwise).

    ``x, y, th``: true pose in the world (m, rad); ``odom_*``: the odometry (the wheels'
    motion since the start, m, rad); ``distance_mm``/``angle_deg``: the same as packets 19
    and 20 count them (mm of the centre, degrees counter-clockwise) since the start.
    ``left, right``: wheel speeds now (m/s); ``set_left, set_right``: asked (m/s).
    ``mode``: 0 off, 1 passive, 2 safe, 3 full. ``bumps_drops``: packet 7.
    """

    distance_mm: float
    angle_deg: float
    left: float
    right: float
    set_left: float
    set_right: float
    mode: int
    bumps_drops: int
    safety_trips: int
    stream: tuple[int, ...] | None
    stream_frames: int
    commands: collections.Counter[str]
    ignored: int
    bad_requests: int
    leds: tuple[int, int, int]
    songs: int
    played: tuple[int, ...]
    baud: int
    battery_mv: int
    battery_mah: int
    frames: int
    dropped_bytes: int
    sim_time: float
    clients: int


class CreateSim(RobotFront):
    """An iRobot Create 2 speaking the Open Interface, in the Pioneer simulator's world.

    ``world``: walls (default :meth:`World.default`); ``start_pose``: m, m, rad (default the
    world's start). ``time_scale``: robot seconds per wall second (physics and the stream run
    that much faster). ``odom_noise``: relative standard deviation of odometry per step, drawn
    from ``seed``. ``bump_stops``: a new bump in safe mode stops the wheels and falls back to
    passive (the specification names only wheel drops, cliffs and the charger).
    """

    def __init__(
        self,
        *,
        world: World | None = None,
        start_pose: Pose | None = None,
        time_scale: float = 1.0,
        odom_noise: float = 0.0,
        seed: int = 0,
        bump_stops: bool = True,
    ) -> None:
        if not time_scale > 0:
            raise ValueError("time_scale must be > 0")
        self.world = world if world is not None else World.default()
        self.time_scale = time_scale
        start = start_pose if start_pose is not None else self.world.start
        self._body = CreateBody(self.world, start, odom_noise, seed)
        self._ctl = CreateController(self._body, bump_stops=bump_stops)
        super().__init__(STREAM_PERIOD_S / time_scale, "create-sim-ticker")

    # ---------------------------------------------------------------- public API

    def serve_tcp(self, host: str = "127.0.0.1", port: int = 0) -> str:
        """Listen on ``host:port`` (0: an ephemeral port), one client at a time (a second is
        refused with a reason). Returns ``tcp://host:port`` with the real port."""
        return self._serve("tcp", lambda s: s.serve_tcp(host, port))

    def serve_pty(self) -> str:
        """Serve on a new pseudo-terminal (raw mode); returns the device a toolkit opens as
        the robot's serial port."""
        return self._serve("pty", lambda s: s.serve_pty())

    def set_pose(self, x: float, y: float, th: float) -> None:
        """Teleport the true pose (m, m, rad); odometry is unchanged."""
        with self._ctl.lock:
            self._body.model.teleport(x, y, th)

    def lift(self, left: bool = True, right: bool = True) -> None:
        """Wheels hanging (a robot picked up, a wheel over a step): packet 7's drop bits."""
        with self._ctl.lock:
            self._body.drops = (DROP_LEFT if left else 0) | (DROP_RIGHT if right else 0)

    def set_cliffs(self, left: bool, front_left: bool, front_right: bool, right: bool) -> None:
        """What the four cliff sensors (packets 9..12) see."""
        with self._ctl.lock:
            self._body.cliffs = (left, front_left, front_right, right)

    def snapshot(self) -> CreateSimState:
        """A consistent copy of the truth (thread-safe)."""
        stats = [s.stats() for s in self._serving()]
        # before the controller lock: a link ending holds its server's lock, then the
        # controller's (detach)
        clients = sum(len(s.links()) for s in self._serving())
        with self._ctl.lock:
            b, c, m = self._body, self._ctl, self._body.model
            left, right = m.wheel_speeds()
            dist, ang = b.travel_mm()
            mv, _, mah, _ = b.battery()
            return CreateSimState(
                x=m.x, y=m.y, th=m.th, odom_x=m.odom[0], odom_y=m.odom[1], odom_th=m.odom[2],
                distance_mm=dist, angle_deg=ang, left=left, right=right,
                set_left=b.set_left, set_right=b.set_right, mode=c.mode,
                bumps_drops=b.bumps() | b.drops, safety_trips=c.safety_trips,
                stream=c.stream, stream_frames=c.stream_frames,
                commands=collections.Counter(c.commands), ignored=c.ignored,
                bad_requests=c.bad_requests, leds=c.actuators.leds,
                songs=len(c.actuators.songs), played=tuple(c.actuators.played),
                baud=c.actuators.baud, battery_mv=mv, battery_mah=mah,
                frames=sum(s.frames for s in stats),
                dropped_bytes=sum(s.dropped_bytes for s in stats),
                sim_time=m.sim_time, clients=clients,
            )  # fmt: skip

    def wait_until(
        self, predicate: Callable[[CreateSimState], bool], timeout: float
    ) -> CreateSimState:
        """Poll snapshots until ``predicate`` holds; raises
        :class:`~robocli.errors.TimeoutError` after ``timeout`` wall seconds."""
        return poll_until(self.snapshot, predicate, timeout)

    # ---------------------------------------------------------------- internals

    def _new_server(self, kind: str) -> Server:
        return Server(
            self._ctl.attach, protocol="create-oi", framer=CommandFramer, max_clients=1,
            max_frame=MAX_COMMAND, byte_timeout=BYTE_TIMEOUT_S, send_timeout=SEND_TIMEOUT_S,
            name=f"create-sim-{kind}",
        )  # fmt: skip

    def _tick(self, now: float) -> None:
        with self._ctl.lock:
            session, data = self._ctl.tick(STREAM_PERIOD_S)
        if session is not None and data:
            session.link.send(data)
