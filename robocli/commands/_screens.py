"""Terminal screens of the Pioneer commands: the live view (fits 80x24, `q` or Ctrl-C
quits), the teleop status line (redrawn at 10 Hz), and raw keyboard input.

Units on screen: metres, m/s, degrees and deg/s (JSON output stays in SI: rad, rad/s).
"""

from __future__ import annotations

import contextlib
import math
import os
import select
import sys
import time
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rich.console import RenderableType

    from robocli.devices.laser import MountedLaser, PlacedScan
    from robocli.devices.pioneer import Pioneer
    from robocli.devices.pioneer.state import PioneerState

#: Seconds between two redraws of the teleop status line (10 Hz).
STATUS_PERIOD = 0.1
QUIT_HINT = "q or Ctrl-C quits"

_ARROWS = {"A": "up", "B": "down", "C": "right", "D": "left"}
KeyReader = Callable[[float], "str | None"]


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
    """A one-line summary of the latest laser scan (nearest return and its bearing, number
    of readings), or None when the robot has no laser scan."""
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


def render(robot: Pioneer, hokuyo: MountedLaser | None = None) -> RenderableType:
    """The live view of ``robot``: at most 18 lines of at most 80 columns."""
    from rich.table import Table

    st = robot.state
    table = Table(
        title=f"{robot.identity.name} ({robot.params.subtype}) {robot.transport.url}"[:78],
        caption=QUIT_HINT,
        show_header=False,
        expand=False,
    )
    table.add_column(style="bold", no_wrap=True)
    table.add_column(no_wrap=True, max_width=66)
    table.add_row("pose", pose_text(st.x, st.y, st.th))
    table.add_row("velocity", velocity_text(st.v, st.w))
    table.add_row(
        "battery",
        f"{st.battery:.1f} V"
        + (f"  {st.state_of_charge:.0%}" if st.state_of_charge is not None else "")
        + "   motors "
        + ("[green]on[/]" if st.motors_enabled else "[yellow]off[/]")
        + ("  [red]E-STOP[/]" if st.estop else ""),
    )
    table.add_row(
        "bumpers",
        f"front {st.bumpers_front:07b}  rear {st.bumpers_rear:07b}"
        + ("  [red]STALL[/]" if st.stalled else ""),
    )
    for i, line in enumerate(sonar_text(robot.sonar)):
        table.add_row("sonar (m)" if i == 0 else "", line)
    laser = laser_text(robot)
    if laser is not None:
        table.add_row("laser", laser)
    placed = hokuyo.latest if hokuyo is not None else None
    if placed is not None:
        table.add_row("hokuyo", hokuyo_text(placed))
    s = robot.stats
    table.add_row(
        "link", f"{s.sips} SIPs  {s.bad_checksums} bad checksums  {s.dropped_bytes} B dropped"
    )
    return table


def live_view(robot: Pioneer, hokuyo: MountedLaser | None = None) -> None:
    """Redraw :func:`render` at every SIP until ``q`` (when stdin is a terminal) or Ctrl-C;
    always leave the cursor on a fresh line. Output that is not a terminal (a pipe, a file)
    gets one line per SIP instead, flushed as it comes: a redrawn screen reaches a pipe only
    when the view ends. ``hokuyo``: a laser on the robot, its latest scan shown too."""
    from rich.live import Live

    if not sys.stdout.isatty():
        while True:
            placed = hokuyo.latest if hokuyo is not None else None
            extra = f"  hokuyo {hokuyo_text(placed)}" if placed is not None else ""
            print(state_line(robot.state) + extra, flush=True)
            robot.wait_for_sip()
    try:
        with keyboard() as read_key, Live(render(robot, hokuyo), auto_refresh=False) as live:
            while True:
                robot.wait_for_sip()
                live.update(render(robot, hokuyo), refresh=True)
                if read_key is not None and read_key(0) in ("q", "Q", "esc"):
                    return
    finally:
        end_line()


def state_line(st: PioneerState) -> str:
    """One line of a SIP for a log or a pipe: receive time, pose, speeds, battery."""
    return (
        f"{st.t:.3f}  {pose_text(st.x, st.y, st.th)}  {velocity_text(st.v, st.w)}  "
        f"battery {st.battery:.1f} V  motors {'on' if st.motors_enabled else 'off'}"
        + ("  STALL" if st.stalled else "")
    )


def end_line() -> None:
    """Move a terminal to a fresh line (after a status line, before any final message)."""
    if sys.stdout.isatty():
        sys.stdout.write("\n")
        sys.stdout.flush()


class StatusLine:
    """The teleop status line: the command and the robot's pose, redrawn in place at
    :data:`STATUS_PERIOD` whether or not the command changes."""

    def __init__(self, robot: Pioneer) -> None:
        self.robot = robot
        self.v = self.w = 0.0
        self._drawn = -math.inf

    def command(self, v: float, w: float) -> None:
        """A new command: remember it and redraw at once."""
        self.v, self.w = v, w
        self.draw()

    def tick(self) -> None:
        """Redraw when :data:`STATUS_PERIOD` has passed since the last draw."""
        if time.monotonic() - self._drawn >= STATUS_PERIOD:
            self.draw()

    def draw(self) -> None:
        x, y, th = self.robot.pose
        sys.stdout.write(
            f"\r{velocity_text(self.v, self.w)}  {pose_text(x, y, th)}  "
            f"{self.robot.battery:4.1f} V "
        )
        sys.stdout.flush()
        self._drawn = time.monotonic()

    def reader(self, read_key: KeyReader) -> KeyReader:
        """``read_key`` that waits at most :data:`STATUS_PERIOD` at a time and redraws."""

        def read(timeout: float) -> str | None:
            self.tick()
            return read_key(min(timeout, STATUS_PERIOD))

        return read


@contextlib.contextmanager
def keyboard() -> Iterator[KeyReader | None]:
    """Keys from stdin in cbreak mode (Ctrl-C still interrupts): yield
    ``read_key(timeout) -> name | None``, or None when stdin is not a terminal."""
    if not sys.stdin.isatty():
        yield None
        return
    with raw_terminal() as read_key:
        yield read_key


@contextlib.contextmanager
def raw_terminal() -> Iterator[KeyReader]:
    """Put stdin in cbreak mode; yield ``read_key(timeout) -> name | None``."""
    import termios
    import tty

    fd = sys.stdin.fileno()
    saved = termios.tcgetattr(fd)

    def read_key(timeout: float) -> str | None:
        ready, _, _ = select.select([fd], [], [], timeout)
        if not ready:
            return None
        ch = os.read(fd, 1)
        if ch == b"\x1b":
            more, _, _ = select.select([fd], [], [], 0.01)
            if not more:
                return "esc"
            seq = os.read(fd, 2)
            return _ARROWS.get(seq[-1:].decode(errors="replace"), None)
        if ch == b"\x03":
            return "ctrl-c"
        if ch == b" ":
            return "space"
        return ch.decode(errors="replace")

    try:
        tty.setcbreak(fd)
        yield read_key
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)
