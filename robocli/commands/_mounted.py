"""A Hokuyo on a Pioneer for ``connect pioneer --laser URL``: connecting it (``sim``: a
simulated one that moves with the robot), and its placed scans as JSON. Thin layers over
:mod:`robocli.devices.laser.mounted`."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

from robocli.commands._common import SIM, rounded

if TYPE_CHECKING:
    from robocli.devices.laser import Laser, PlacedScan
    from robocli.devices.pioneer import Pioneer

__all__ = ["on_robot", "placed_json"]

#: JSON decimals by field: 1 mm ranges, angles to 1e-6 rad, points to 0.1 mm.
RESOLUTION = {"t": 6, "received": 6, "ranges": 3, "angles": 6, "intensities": 0,
              "points_robot": 4, "points_odom": 4}  # fmt: skip


@contextlib.contextmanager
def on_robot(port: str, robot: Pioneer, model: str = "utm-30lx", world: Any = None,
             **options: Any) -> Iterator[Laser]:  # fmt: skip
    """A laser on ``port`` mounted on ``robot``. For ``sim``: a simulated one in ``world``
    (default: the simulators' default room), placed after every SIP at the robot's odometric
    pose (from the world's start) composed with the robot model's mount, so that it sees the
    room the Pioneer simulator's robot is in (``PORT sim``, or ``robocli sim pioneer``
    without ``--map``)."""
    from robocli.devices.laser import Laser

    if port != SIM:
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
    import threading

    from robocli.errors import RobocliError
    from robocli.robots.geometry import Mount

    mount, start, stop = robot.params.laser_mount, sim.world.start, threading.Event()

    def place() -> None:
        sim.set_pose(mount.place(Mount(*robot.pose).place(start)))

    def follow() -> None:
        while not stop.is_set():
            try:
                robot.wait_for_sip(0.5)
                place()
            except RobocliError:
                if not robot.alive:
                    return

    place()
    thread = threading.Thread(target=follow, name="hokuyo-sim-follow", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join(2.0)


def placed_json(placed: PlacedScan) -> dict[str, Any]:
    """A placed scan as JSON-ready SI data (see :meth:`PlacedScan.as_dict`)."""
    return rounded(placed.as_dict(), 6, RESOLUTION)  # type: ignore[no-any-return]
