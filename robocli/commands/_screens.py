"""Terminal screens of the Pioneer commands: the live view (fits 80x24, `q` or Ctrl-C
quits) and the teleop status line (redrawn at 10 Hz), drawn from :mod:`robocli.views`.

Units on screen: metres, m/s, degrees and deg/s (JSON output stays in SI: rad, rad/s).
"""

from __future__ import annotations

import contextlib
import math
import sys
import time
from collections.abc import Iterator
from typing import TYPE_CHECKING

from robocli.views.keys import QUIT_KEYS, KeyReader, keyboard, raw_terminal
from robocli.views.pioneer import hokuyo_text, laser_text, pose_text, sonar_text, velocity_text
from robocli.views.pioneer import state_line as state_line

if TYPE_CHECKING:
    from rich.console import RenderableType

    from robocli.devices.laser import MountedLaser
    from robocli.devices.pioneer import Pioneer

#: Seconds between two redraws of the teleop status line (10 Hz).
STATUS_PERIOD = 0.1
QUIT_HINT = "q or Ctrl-C quits"


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
                if read_key is not None and read_key(0) in QUIT_KEYS:
                    return
    finally:
        end_line()


def end_line() -> None:
    """Move a terminal to a fresh line (after a status line, before any final message)."""
    if sys.stdout.isatty():
        sys.stdout.write("\n")
        sys.stdout.flush()


@contextlib.contextmanager
def keys() -> Iterator[KeyReader]:
    """``read_key(timeout)`` of the terminal in cbreak mode, restored afterwards; the cursor
    left on a fresh line after the status line however the loop ends."""
    try:
        with raw_terminal() as read_key:
            yield read_key
    finally:
        end_line()


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
