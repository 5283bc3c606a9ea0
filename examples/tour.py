"""The README's Python tour: one script drives a Pioneer wherever it is; only the URL changes.
``python examples/tour.py URL``, URL one of ``sim://`` (the built-in simulator),
``tcp://127.0.0.1:8101`` (``robocli sim pioneer``, MobileSim), ``/dev/ttyUSB0`` (a serial
port, or a pty), ``"zenoh/r1?zenoh=tcp/127.0.0.1:7447"`` (behind ``robocli bridge pioneer``).
"""

import math
import sys
import time

from robocli import Pioneer

url = sys.argv[1] if len(sys.argv) > 1 else "sim://"
with Pioneer.connect(url) as robot:  # URLs: docs/urls.md
    print(f"connected to {url}: battery {robot.state.battery:.1f} V, pose {robot.pose}")
    robot.enable_motors()
    x0, y0, _ = robot.pose  # metres, radians
    robot.set_velocity(0.3, 0.0)  # SI units: m/s, rad/s
    deadline = time.monotonic() + 30.0
    while math.dist(robot.pose[:2], (x0, y0)) < 0.25 and time.monotonic() < deadline:
        robot.wait_for_state()  # until 25 cm driven: the next state from the robot
    robot.stop()
    x, y, th = robot.pose
    print(f"drove from x={x0:.3f} y={y0:.3f} to x={x:.3f} y={y:.3f} th={th:.3f}")
# leaving the block (or Ctrl-C, an exception, a lost link) stops the robot and closes the link
