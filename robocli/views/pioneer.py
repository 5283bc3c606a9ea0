"""A Pioneer's state as the live views show it: one-line summaries in metres, m/s, degrees
and deg/s, and the JSON-ready snapshot (SI: m, rad, m/s, rad/s; ``t`` in Unix time)."""

from __future__ import annotations

import contextlib
import math
from typing import TYPE_CHECKING, Any

from robocli.errors import TimeoutError
from robocli.io.jsonlines import unix_stamped

if TYPE_CHECKING:
    from robocli.devices.laser import PlacedScan
    from robocli.devices.pioneer import Pioneer
    from robocli.devices.pioneer.state import PioneerState

__all__ = ["hokuyo_text", "laser_text", "pose_text", "snapshot", "snapshot_lines", "sonar_text",
           "start_laser", "state_line", "velocity_text"]  # fmt: skip


def pose_text(x: float, y: float, th: float) -> str:
    """``x +1.234 m  y -0.500 m  th +90.0 deg``: the pose as every human view shows it."""
    return f"x {x:+.3f} m  y {y:+.3f} m  th {math.degrees(th):+.1f} deg"


def velocity_text(v: float, w: float) -> str:
    """``v +0.200 m/s  w +10.0 deg/s``: speeds as every human view shows them."""
    return f"v {v:+.3f} m/s  w {math.degrees(w):+.1f} deg/s"


def sonar_text(ranges: Any) -> list[str]:
    """Sonar ranges (m) as lines of 8 values, ``-`` for none."""
    cells = ["  -  " if r is None or math.isnan(r) else f"{r:5.2f}" for r in ranges]
    return [" ".join(cells[i : i + 8]) for i in range(0, len(cells), 8)]


def laser_text(robot: Pioneer) -> str | None:
    """A one-line summary of the simulator's latest laser scan (nearest return and its
    bearing, number of readings), or None when the robot has no laser scan."""
    scan = robot.sim.laser if robot.sim is not None else None
    if scan is None:
        return None
    nearest = scan.nearest()
    if nearest is None:
        return f"nothing in range  ({len(scan)} readings)"
    rng, bearing = nearest
    return f"nearest {rng:.2f} m at {math.degrees(bearing):+.0f} deg  ({len(scan)} readings)"


def hokuyo_text(placed: PlacedScan) -> str:
    """A one-line summary of a Hokuyo scan placed on the robot: the nearest return, its
    bearing from the robot and where it is in the odometry frame, and the valid count."""
    import numpy as np

    scan = placed.scan
    n, valid = len(scan.ranges), int(np.count_nonzero(scan.valid))
    if not valid:
        return f"nothing in range  (0/{n} valid)"
    robot_xy, odom_xy = placed.robot_points, placed.odom_points
    i = int(np.nanargmin(np.hypot(robot_xy[:, 0], robot_xy[:, 1])))
    rng = math.hypot(*robot_xy[i])
    bearing = math.atan2(robot_xy[i, 1], robot_xy[i, 0])
    return (f"nearest {rng:.2f} m at {math.degrees(bearing):+.0f} deg, odom "
            f"({odom_xy[i, 0]:+.2f}, {odom_xy[i, 1]:+.2f}) m  ({valid}/{n} valid)")  # fmt: skip


def state_line(st: PioneerState) -> str:
    """One line of a SIP for a log or a pipe: receive time, pose, speeds, battery."""
    return (
        f"{st.t:.3f}  {pose_text(st.x, st.y, st.th)}  {velocity_text(st.v, st.w)}  "
        f"battery {st.battery:.1f} V  motors {'on' if st.motors_enabled else 'off'}"
        + ("  STALL" if st.stalled else "")
    )


def snapshot_lines(robot: Pioneer, hokuyo: PlacedScan | None = None) -> list[str]:
    """``connect pioneer --once``: the robot, its pose, velocity, battery, sonar and lasers
    (``hokuyo``: a scan placed on it), a line each."""
    st, ident = robot.state, robot.identity
    out = [f"{ident.name} {ident.type} {ident.subtype} on {robot.transport.url}",
           f"pose      {pose_text(st.x, st.y, st.th)}", f"velocity  {velocity_text(st.v, st.w)}",
           f"battery   {st.battery:.1f} V   motors {'on' if st.motors_enabled else 'off'}"]
    sonar = sonar_text(robot.sonar)
    out += [f"{'sonar (m)' if i == 0 else '':10}{line}" for i, line in enumerate(sonar)]
    laser = laser_text(robot)
    out += [f"laser     {laser}"] if laser is not None else []
    return out + ([f"hokuyo    {hokuyo_text(hokuyo)}"] if hokuyo is not None else [])


def start_laser(robot: Pioneer, wait: bool) -> None:
    """On a simulator (MobileSim, robocli sim), ask for its laser; with ``wait``, wait up
    to a second for the first scan. Real robots are left alone (their laser has its own
    port)."""
    if robot.sim is None:
        return
    robot.sim.start_laser()
    if wait:
        with contextlib.suppress(TimeoutError):
            robot.sim.wait_for_laser(1.0)


def snapshot(robot: Pioneer, **extra: Any) -> dict[str, Any]:
    """:meth:`Pioneer.snapshot <robocli.devices.pioneer.Pioneer.snapshot>` with its state's
    ``t`` in Unix time (``t_mono`` kept), then ``extra``'s fields, then the simulator's
    latest laser scan when it has one (ranges in m, None where nothing was seen; angles in
    rad)."""
    data = robot.snapshot()
    data["state"] = unix_stamped(data["state"])
    data.update(extra)
    scan = robot.sim.laser if robot.sim is not None else None
    if scan is not None and "laser" not in data:
        data["laser"] = unix_stamped({
            "t": scan.t,
            "pose": dict(zip(("x", "y", "th"), scan.pose, strict=True)),
            "angles": list(scan.angles),
            "ranges": [None if math.isinf(r) else r for r in scan.ranges],
        })  # fmt: skip
    return data
