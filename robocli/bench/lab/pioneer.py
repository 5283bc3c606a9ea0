"""A class watches one Pioneer that one laptop drives, in the lab's namespaces, and the
robot stops when the driver is killed.

The robot's namespace runs ``robocli sim pioneer`` (on its loopback) and ``robocli bridge
pioneer ... --zenoh tcp/<robot address>:7447`` (a server: it listens there). Laptop 0 drives
(:class:`~robocli.bridge.RemotePioneer`, ``set_velocity``); every other laptop watches, each
printing the velocity of every state the bridge puts, with its receive time on the host's
one clock. The bench kills the driver's process (SIGKILL: no goodbye) and reads, in each
watcher's log, when the robot's velocity came to zero.

``python -m robocli.bench.lab.pioneer drive|watch ROBOT ENDPOINT`` is the laptop side.
"""

from __future__ import annotations

import json
import os
import signal
import sys
import time
from dataclasses import dataclass, field
from typing import Any

from robocli.bench.lab.netns import Lab, LabError, Proc, wait_for

BRIDGE_PORT = 7447
PIONEER_PORT = 8101
START_S = 60.0
DRIVE_V = 0.3  #: m/s
MOVING = 0.1  #: m/s: a watcher sees the robot move above this
STOPPED = 0.005  #: m/s: and stopped below this


@dataclass
class PioneerRun:
    """What the class saw: watchers that saw the robot move, and for each watcher the
    delay from the driver's death to the first state with the robot stopped."""

    laptops: int
    watchers_moving: int = 0
    stop_delays: list[float] = field(default_factory=list)
    silence: float = 0.5

    def as_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


def class_drives_pioneer(laptops: int = 3, *, uplink_mbit: float | None = 20.0) -> PioneerRun:
    """A lab of one robot and ``laptops`` laptops (at least 2): laptop 0 drives, the others
    watch; the driver is killed once every watcher saw the robot move."""
    if laptops < 2:
        raise LabError("a driver and at least one watcher: 2 laptops or more")
    result = PioneerRun(laptops)
    py = sys.executable
    with Lab(1, laptops, uplink_mbit=uplink_mbit) as lab:
        robot = lab.robot(0)
        endpoint = f"tcp/{robot.address}:{BRIDGE_PORT}"
        sim = lab.spawn(robot, [py, "-m", "robocli", "sim", "pioneer", "--port",
                                str(PIONEER_PORT)], "pioneer-sim")  # fmt: skip
        wait_for(lambda: "tcp://" in sim.tail(), START_S, "the simulated Pioneer", [sim])
        bridge = lab.spawn(robot, [py, "-m", "robocli", "bridge", "pioneer",
                                   f"tcp://127.0.0.1:{PIONEER_PORT}", "--zenoh", endpoint,
                                   "--name", "r0", "--silence", str(result.silence)],
                           "bridge")  # fmt: skip
        wait_for(lambda: "bridge r0" in bridge.tail(), START_S, "the bridge", [bridge, sim])
        me = "robocli.bench.lab.pioneer"
        watchers = [lab.spawn(lab.laptop(j), [py, "-m", me, "watch", "r0", endpoint],
                              f"watcher{j}") for j in range(1, laptops)]  # fmt: skip
        for w in watchers:
            wait_for(lambda w=w: "watching" in w.tail(), START_S, f"{w.name}", [w, bridge])
        driver = lab.spawn(lab.laptop(0), [py, "-m", me, "drive", "r0", endpoint], "driver")

        def moving(w: Proc) -> bool:
            return any(s["v"] > MOVING for s in w.json_lines(100_000))

        wait_for(lambda: all(moving(w) for w in watchers), START_S, "the class seeing the "
                 "robot move", [driver, bridge, *watchers])  # fmt: skip
        result.watchers_moving = sum(moving(w) for w in watchers)
        killed = time.time()
        os.killpg(driver.pid, signal.SIGKILL)

        def stopped_at(w: Proc) -> float | None:
            return next((s["t"] for s in w.json_lines(100_000) if s["t"] > killed and
                         abs(s["v"]) < STOPPED), None)  # fmt: skip

        wait_for(lambda: all(stopped_at(w) is not None for w in watchers), START_S,
                 "the robot stopping", [bridge, *watchers])  # fmt: skip
        result.stop_delays = [float(stopped_at(w) or 0.0) - killed for w in watchers]
    return result


def main(argv: list[str] | None = None) -> int:
    from robocli.bridge import RemotePioneer

    args = sys.argv[1:] if argv is None else argv
    if len(args) != 3 or args[0] not in ("drive", "watch"):
        print("usage: python -m robocli.bench.lab.pioneer drive|watch ROBOT ENDPOINT",
              file=sys.stderr)  # fmt: skip
        return 2
    role, robot, endpoint = args
    holder = f"{role}-{os.getpid()}"
    with RemotePioneer.connect(robot, endpoint, holder=holder, timeout=20.0) as remote:
        if role == "drive":
            remote.set_velocity(DRIVE_V)
            print("driving", flush=True)
            while True:  # until killed: the bridge re-sends nothing, RemotePioneer does
                time.sleep(1.0)
        print("watching", flush=True)
        while True:
            try:
                state = remote.wait_for_state(5.0)
            except TimeoutError:
                continue
            print(json.dumps({"t": time.time(), "v": state.v, "x": state.x}), flush=True)


if __name__ == "__main__":
    sys.exit(main())
