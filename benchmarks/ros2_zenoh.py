"""What ``--ros2`` costs (docs/ros2.md has the figures):

* ``--bridge``: a Pioneer (the built-in simulator, in this process) bridged with ``--ros2``:
  the delay from a SIP's arrival at the client (the time its reader stamps it with) to the
  return of the put of the ``odom`` message it maps to (decode, map to ROS 2, CDR, attach,
  put), over ``--seconds`` of SIPs (10 Hz), with a ROS 2 subscriber of ``0/**`` attached;
  and the CPU time the sink's thread spends per received frame (a load-free bound of the
  delay on an idle core).
* ``--hub``: ``robocli serve --sim --no-tcp --zenoh`` publishing the full sensor set
  (adc, imu, gps, battery, sysinfo, camera, stereo, depth, laser), without and with
  ``--ros2``: the hub process's CPU (cores, from /proc/PID/stat) over ``--seconds``, with one
  subscriber of everything (robocli's keys and ROS 2's) in another process. Linux only.

    python benchmarks/ros2_zenoh.py --bridge --hub --seconds 20
"""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import time
from typing import Any

import numpy as np

FULL_SET = "adc,imu,gps,battery,sysinfo,camera,stereo,depth,laser"
CLK = os.sysconf("SC_CLK_TCK")


def free_endpoint() -> str:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{s.getsockname()[1]}"


def bridge_delay(seconds: float) -> dict[str, float]:
    """SIP -> ROS 2 put of its odometry, in ms (see the module)."""
    from robocli.bridge.pioneer import PioneerBridge
    from robocli.bridge.ros2 import Ros2Bridge
    from robocli.devices.pioneer import Pioneer
    from robocli.io.record.pioneer import attach_pioneer
    from robocli.sim.pioneer.server import PioneerSim
    from robocli.zenoh.session import open_session

    endpoint = free_endpoint()
    delays: list[float] = []
    cpu: list[float] = []  # the sink thread's CPU per received frame (SIP or not)
    with PioneerSim() as sim:
        url = sim.serve_tcp("127.0.0.1", 0)
        session = open_session(endpoint, "server")
        watcher = open_session(endpoint, "client")
        watcher.declare_subscriber("0/**", lambda s: None)
        with Pioneer.connect(url) as robot, PioneerBridge(robot, session, "p1") as bridge:
            ros = Ros2Bridge(session, "p1", bridge.gate)
            topics, current = ros.topics, [0.0]
            put = topics.put

            def timed_put(handler: Any, args: tuple[Any, ...], size: int = 64) -> bool:
                if len(args) == 3 and args[0] == "rx":
                    t = args[2]

                    def timed(*a: Any) -> None:
                        current[0] = t
                        c0 = time.thread_time()
                        handler(*a)
                        cpu.append(time.thread_time() - c0)

                    return put(timed, args, size)
                return put(handler, args, size)

            topics.put = timed_put  # type: ignore[method-assign]
            attach_pioneer(topics, robot, "p1")
            odom = topics.publisher("odom", "nav_msgs/msg/Odometry")
            publish = odom.publish

            def timed_publish(cdr: bytes, t_ns: int | None = None) -> None:
                publish(cdr, t_ns)
                delays.append(time.monotonic() - current[0])

            odom.publish = timed_publish  # type: ignore[method-assign]
            time.sleep(seconds)
            ros.close()
        watcher.close()
        session.close()
    ms = np.array(delays) * 1e3
    return {"sips": float(len(ms)), "p50_ms": float(np.percentile(ms, 50)),
            "p99_ms": float(np.percentile(ms, 99)), "max_ms": float(ms.max()),
            "cpu_per_frame_ms_p50": float(np.percentile(cpu, 50)) * 1e3,
            "cpu_per_frame_ms_p99": float(np.percentile(cpu, 99)) * 1e3}  # fmt: skip


def _cpu(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK


def hub_cores(seconds: float, ros2: bool, ros_reader: bool = True) -> float:
    """The hub's cores serving the full sensor set on Zenoh (with ``--ros2``: also ROS 2;
    ``ros_reader``: a subscriber of every ROS 2 topic, else of robocli's keys only)."""
    endpoint = free_endpoint()
    args = [sys.executable, "-m", "robocli", "serve", "--sim", "--no-tcp", "--zenoh", endpoint,
            "--publish", FULL_SET, "--name", "hub1", *(["--ros2"] if ros2 else [])]  # fmt: skip
    hub = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    assert hub.stdout is not None
    hub.stdout.readline()  # listening
    reader = subprocess.Popen([sys.executable, "-c", (
        "import sys, time, zenoh\n"
        "c = zenoh.Config(); c.insert_json5('mode', '\"client\"')\n"
        f"c.insert_json5('connect/endpoints', '[\"{endpoint}\"]')\n"
        "c.insert_json5('scouting/multicast/enabled', 'false')\n"
        "s = zenoh.open(c); n = [0]\n"
        "s.declare_subscriber('robocli/**', lambda x: n.__setitem__(0, n[0] + 1))\n"
        + ("s.declare_subscriber('0/**', lambda x: n.__setitem__(0, n[0] + 1))\n"
           if ros_reader else "") +
        "time.sleep(float(sys.argv[1]))\n"
        "print(n[0])\n"), str(seconds + 10)], stdout=subprocess.PIPE, text=True)  # fmt: skip
    try:
        time.sleep(3.0)  # sessions up, publishers declared
        c0, t0 = _cpu(hub.pid), time.monotonic()
        time.sleep(seconds)
        return (_cpu(hub.pid) - c0) / (time.monotonic() - t0)
    finally:
        for proc in (hub, reader):
            proc.terminate()
            proc.wait(10)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bridge", action="store_true")
    parser.add_argument("--hub", action="store_true")
    parser.add_argument("--seconds", type=float, default=10.0)
    a = parser.parse_args()
    if a.bridge:
        print("bridge SIP -> ROS 2 odom put:", bridge_delay(a.seconds))
    if a.hub:
        without = hub_cores(a.seconds, False)
        unread = hub_cores(a.seconds, True, ros_reader=False)
        read = hub_cores(a.seconds, True)
        print(
            f"hub full set: {without:.3f} cores without --ros2; with --ros2 {unread:.3f} "
            f"(no ROS 2 subscriber), {read:.3f} (a subscriber of every ROS 2 topic)"
        )


if __name__ == "__main__":
    main()
