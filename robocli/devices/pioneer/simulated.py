"""What a Pioneer client can do with a simulator (MobileSim, AMRISim, ``robocli sim``): its
simulated laser, its status (true pose, GPS), teleporting the robot. A part of
:class:`~robocli.devices.pioneer.Pioneer`, reached as ``robot.sim`` (None on a real robot);
the laser and SIMSTAT packets are decoded by :mod:`robocli.devices.pioneer.laser`.

>>> with Pioneer.connect("sim://", laser=True) as robot:   # doctest: +SKIP
...     scan = robot.sim.wait_for_laser()
...     scan.nearest()                      # (range m, bearing rad) of the closest return
...     robot.sim.status().true_pose        # where the simulator really has the robot
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol

from robocli.devices.pioneer.laser import (
    LaserScan,
    LaserSettings,
    ScanAssembler,
    SimStatus,
    parse_simstatus,
)
from robocli.devices.session import Listeners
from robocli.errors import DeviceError, InvalidArgument, TimeoutError
from robocli.protocols import arcos
from robocli.protocols.arcos import Command, PacketType

if TYPE_CHECKING:
    from robocli.devices.pioneer.link import PioneerStats
    from robocli.devices.pioneer.state import PioneerState, RobotIdentity
    from robocli.devices.session import Session
    from robocli.transports import Transport


class _Robot(Protocol):
    """What :class:`PioneerSimulator` uses of the Pioneer it belongs to."""

    _session: Session
    _sip: Any
    identity: RobotIdentity
    config: dict[str, Any] | None
    transport: Transport
    stats: PioneerStats
    sip_timeout: float

    @property
    def is_simulator(self) -> bool: ...

    def _current_state(self) -> PioneerState: ...


__all__ = ["LaserListener", "PioneerSimulator", "is_simulator"]

#: Laser listener signature: called with each complete scan, in the thread that read it.
LaserListener = Callable[[LaserScan], None]

#: Names a simulator gives itself in the SYNC2 reply; the CONFIG serial ``SIM`` also tells.
SIMULATOR_NAMES = frozenset({"MobileSim", "AMRISim"})

#: The commands of each set: enable, FOV start, FOV end, resolution.
_OLD = (Command.ADSEL, Command.GRIPPERVAL, Command.GRIPREQUEST, Command.GYROCALCW)
_NEW = (Command.SIM_LRF_ENABLE, Command.SIM_LRF_FOV_START, Command.SIM_LRF_FOV_END,
        Command.SIM_LRF_RES)  # fmt: skip


def is_simulator(name: str, config: dict[str, Any] | None) -> bool:
    """A robot is a simulator when it says so in its name or its CONFIG serial (``SIM``),
    the vendor SDK's test before it asks for the simulated laser."""
    return name in SIMULATOR_NAMES or (config or {}).get("serial") == "SIM"


class PioneerSimulator:
    """``robot.sim``: the simulated laser, the simulator's status, teleporting (see the
    module). Made by the :class:`~robocli.devices.pioneer.Pioneer` it belongs to."""

    def __init__(self, robot: _Robot) -> None:
        self._robot = robot
        self._session = robot._session
        self._laser: LaserScan | None = None
        self._laser_settings = LaserSettings()
        self._scans = ScanAssembler(robot.stats.add)
        #: the laser's listeners (``robot.add_listener(f, kind="laser")``)
        self.listeners: Listeners[LaserListener] = Listeners(robot.stats, "pioneer laser")

    def _check_simulator(self, what: str) -> None:
        robot = self._robot
        if not robot.is_simulator:
            raise DeviceError(
                f"{robot.transport.url}: {robot.identity.name} is not a simulator (serial "
                f"{(robot.config or {}).get('serial')!r}); {what}"
            )

    # ------------------------------------------------------------------ laser

    @property
    def laser(self) -> LaserScan | None:
        """The latest complete laser scan (None before the first one)."""
        with self._session.cond:
            return self._laser

    def start_laser(
        self, start: float = -math.pi / 2, end: float = math.pi / 2,
        resolution: float = math.radians(1.0), *, extended: bool = True,
        max_range: float = 32.0, new_commands: bool = False,
    ) -> None:  # fmt: skip
        """Ask a simulator for its laser: field of view ``start``..``end`` and ``resolution``
        (rad; sent as whole degrees and hundredths of a degree), extended scans (0x61, with
        reflectance) or plain ones (0x60). ``max_range`` (m): longer readings count as no
        return. By default the commands the vendor SDK sends (36, 37, 38, 35), else the newer
        230-233 (MobileSim >= 0.6). Scans then arrive after every SIP (:attr:`laser`,
        ``robot.add_listener(f, kind="laser")``, :meth:`wait_for_laser`).

        Raises :class:`DeviceError` on a real robot (its 35-38 are ADSEL, gripper and gyro
        commands; a real laser has its own port) and :class:`InvalidArgument` for a field of
        view or resolution that does not fit.
        """
        values = {"start": start, "end": end, "resolution": resolution, "max_range": max_range}
        for name, value in values.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise InvalidArgument(f"{name} must be a number, not {value!r}")
            if not math.isfinite(value):
                raise InvalidArgument(f"{name} must be finite, not {value!r}")
        if not -math.pi <= start <= math.pi or not -math.pi <= end <= math.pi or start == end:
            raise InvalidArgument("start and end must be distinct angles within -pi..pi rad")
        res_cdeg = round(math.degrees(resolution) * 100)
        if not 1 <= res_cdeg <= 18000 or max_range <= 0:
            raise InvalidArgument("resolution must be 0.01..180 deg and max_range > 0")
        self._check_simulator("a real laser connects on its own port")
        enable, cmd_start, cmd_end, cmd_res = _NEW if new_commands else _OLD
        s0, s1 = round(math.degrees(start)), round(math.degrees(end))
        settings = LaserSettings(s0, s1, res_cdeg, max_range)
        with self._session.cond:
            self._laser_settings = settings
        packets = [
            arcos.encode_command(cmd_start, s0), arcos.encode_command(cmd_end, s1),
            arcos.encode_command(cmd_res, res_cdeg),
            arcos.encode_command(enable, 2 if extended else 1),
        ]  # fmt: skip
        self._session.send_many(packets)  # one write, as the vendor SDK

    def stop_laser(self, *, new_commands: bool = False) -> None:
        """Switch the simulated laser off (one more scan may still come)."""
        self._session.send(arcos.encode_command((_NEW if new_commands else _OLD)[0], 0))

    def wait_for_laser(self, timeout: float | None = None) -> LaserScan:
        """Block until the next complete scan arrives and return it (``timeout`` defaults to
        ``sip_timeout``); :class:`TimeoutError` if none comes."""
        limit = self._robot.sip_timeout if timeout is None else timeout
        deadline = time.monotonic() + limit
        cond = self._session.cond
        with cond:
            before = self._laser
            while True:
                self._session.check()
                if self._laser is not before and self._laser is not None:
                    return self._laser
                left = deadline - time.monotonic()
                if left <= 0:
                    url = self._robot.transport.url
                    raise TimeoutError(f"{url}: no laser scan within {limit:g} s")
                cond.wait(left)

    def _on_laser(self, ptype: int, body: bytes, now: float) -> None:
        """A laser packet (reader thread or a waiting caller): assemble, publish, notify."""
        robot = self._robot
        with self._session.cond:
            pose = robot._current_state().pose if robot._sip is not None else (0.0, 0.0, 0.0)
            settings = self._laser_settings
        scan = self._scans.feed(ptype, body, now, pose, settings)
        if scan is not None:
            with self._session.cond:
                self._laser = scan
                self._session.cond.notify_all()
            self.listeners.notify(scan)

    # ------------------------------------------------------------------ status

    def status(self, timeout: float = 2.0) -> SimStatus:
        """Ask the simulator for its status (SIM_STAT 1 -> 0x62): true pose, step timing,
        GPS fix with a georeferenced map. Raises :class:`DeviceError` on a real robot and
        :class:`TimeoutError` when no reply comes (a simulator without SIMSTAT)."""
        self._check_simulator("it has no simulator status")
        frame = self._session.request(
            arcos.encode_command(Command.SIM_STAT, 1), _is_simstat, timeout
        )
        return parse_simstatus(frame[4:-2], time.monotonic())

    def set_pose(self, x: float, y: float, th: float) -> None:
        """Teleport the robot's true pose (m, m, rad), as MobileSim's SIM_SET_POSE does."""
        self._session.send(
            arcos.encode_sim_pose(round(x * 1000), round(y * 1000), round(math.degrees(th)))
        )


def _is_simstat(frame: bytes) -> bool:
    return frame[3] == PacketType.SIM_STAT
