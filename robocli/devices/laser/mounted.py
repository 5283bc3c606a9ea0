"""A Hokuyo on a robot: its scans placed in the robot's frame and in the odometry frame.

>>> from robocli.devices.laser.mounted import scan_points            # doctest: +SKIP
>>> scan = laser.scan()
>>> xy = scan_points(scan, robot.pose, robot.params.laser_mount)    # (N, 2), odom frame, m

The mount is the robot model's (:attr:`robocli.robots.pioneer.RobotParams.laser_mount`, from
the vendor's ``params/*.p``: the P3-DX's laser sits 18 mm ahead of its centre). A scan is
placed with the robot's odometric pose when it arrived (the latest SIP's), as the vendor SDK
does. :class:`MountedLaser` does that for every streamed scan.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from robocli.closing import in_background
from robocli.errors import RobocliError, TimeoutError
from robocli.robots.geometry import Mount

if TYPE_CHECKING:
    from robocli.devices.laser.client import Laser
    from robocli.devices.laser.scan import Scan
    from robocli.devices.pioneer import Pioneer

__all__ = ["MountedLaser", "PlacedScan", "on_robot", "scan_points"]

FloatArray = npt.NDArray[np.float64]
Pose = tuple[float, float, float]


_CENTRE = Mount()


def scan_points(scan: Scan, pose: Pose = (0.0, 0.0, 0.0), mount: Mount = _CENTRE) -> FloatArray:
    """The readings of ``scan`` as an (N, 2) array of x, y (m) in the frame where the robot
    is at ``pose`` (m, m, rad; the default: the robot's own frame), the laser sitting at
    ``mount`` on the robot. Row ``i`` is reading ``i``; NaN where the sensor sent an error
    code (no range)."""
    sx, sy, sth = mount.place(pose)
    angles = -scan.angles if mount.flipped else scan.angles
    a = angles + sth
    r = scan.ranges
    out: FloatArray = np.column_stack((sx + r * np.cos(a), sy + r * np.sin(a)))
    return out


def _xy(points: FloatArray) -> list[list[float] | None]:
    return [None if math.isnan(x) else [round(float(x), 4), round(float(y), 4)]
            for x, y in points]  # fmt: skip


@dataclass(frozen=True, eq=False)
class PlacedScan:
    """A scan with the robot's odometric ``pose`` (m, m, rad) when it arrived and the
    laser's ``mount`` on the robot."""

    scan: Scan
    pose: Pose
    mount: Mount

    @property
    def robot_points(self) -> FloatArray:
        """(N, 2) points in the robot's frame (``base_link``), NaN rows for no range."""
        return scan_points(self.scan, (0.0, 0.0, 0.0), self.mount)

    @property
    def odom_points(self) -> FloatArray:
        """(N, 2) points in the odometry frame, NaN rows for no range."""
        return scan_points(self.scan, self.pose, self.mount)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: the scan's ``t`` (Unix epoch s), ``ranges`` (m, None for an error
        code), ``angles`` (rad, the sensor's), ``codes``; the robot's ``pose``, the
        ``mount``, and each reading as ``[x, y]`` in the robot frame (``points_robot``) and
        the odometry frame (``points_odom``), None where there is no range."""
        m = self.mount
        return {
            **self.scan.as_dict(),
            "pose": dict(zip(("x", "y", "th"), self.pose, strict=True)),
            "mount": {"x": m.x, "y": m.y, "th": m.th, "flipped": m.flipped},
            "points_robot": _xy(self.robot_points), "points_odom": _xy(self.odom_points),
        }  # fmt: skip


class MountedLaser:
    """A streaming :class:`~robocli.devices.laser.Laser` on a
    :class:`~robocli.devices.pioneer.Pioneer`: every streamed scan is paired with the robot's
    pose when it arrived (:attr:`latest`, :meth:`wait`). ``mount`` defaults to the robot
    model's. Start the stream with ``laser.start()``; :meth:`close` stops listening."""

    def __init__(self, laser: Laser, robot: Pioneer, mount: Mount | None = None) -> None:
        self.laser, self.robot = laser, robot
        self.mount = robot.params.laser_mount if mount is None else mount
        self.scans = 0  #: scans placed
        self._latest: PlacedScan | None = None
        self._cond = threading.Condition()
        laser.add_listener(self._on_scan, kind="scans")

    def place(self, scan: Scan) -> PlacedScan:
        """``scan`` with the robot's latest pose."""
        return PlacedScan(scan, self.robot.pose, self.mount)

    def _on_scan(self, scan: Scan) -> None:
        try:
            placed = self.place(scan)
        except RobocliError:  # the robot's link is gone: its own reader says why
            return
        with self._cond:
            self._latest = placed
            self.scans += 1
            self._cond.notify_all()

    @property
    def latest(self) -> PlacedScan | None:
        """The last placed scan (None before the first)."""
        return self._latest

    def wait(self, timeout: float = 2.0) -> PlacedScan:
        """The next placed scan; :class:`~robocli.errors.TimeoutError` after ``timeout`` s."""
        deadline = time.monotonic() + timeout
        with self._cond:
            seen = self.scans
            while self.scans == seen:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(f"{self.laser.url}: no scan within {timeout:g} s")
                self._cond.wait(left)
            assert self._latest is not None
            return self._latest

    def close(self) -> None:
        """Stop listening to the laser (idempotent; the laser stays open)."""
        self.laser.remove_listener(self._on_scan, kind="scans")


@contextlib.contextmanager
def on_robot(port: str, robot: Pioneer, model: str = "utm-30lx", world: Any = None,
             **options: Any) -> Iterator[Laser]:  # fmt: skip
    """A laser on ``port`` mounted on ``robot``. For ``sim``: a simulated one in ``world``
    (default: the simulators' default room), placed after every SIP at the robot's odometric
    pose (from the world's start) composed with the robot model's mount, so that it sees the
    room the Pioneer simulator's robot is in (``PORT sim``, or ``robocli sim pioneer``
    without ``--map``)."""
    from robocli.devices.laser import Laser

    if port != "sim":
        with Laser.connect(port, **options) as laser:
            yield laser
        return
    from robocli.sim.hokuyo import HokuyoSim

    with HokuyoSim(model, world=world) as sim, _following(sim, robot):
        with Laser.connect(sim.serve_tcp("127.0.0.1", 0), **options) as laser:
            yield laser


@contextlib.contextmanager
def _following(sim: Any, robot: Pioneer) -> Iterator[None]:
    """Move ``sim`` (a HokuyoSim) with ``robot``'s odometry until the block ends."""
    mount, start = robot.params.laser_mount, sim.world.start

    def place() -> None:
        sim.set_pose(mount.place(Mount(*robot.pose).place(start)))

    def follow(stop: threading.Event) -> None:
        while not stop.is_set():
            try:
                robot.wait_for_sip(0.5)
                place()
            except RobocliError:
                if not robot.alive:
                    return

    place()
    with in_background(follow, "hokuyo-sim-follow", 2.0):
        yield
