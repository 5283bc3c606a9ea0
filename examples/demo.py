"""`make demo`: a short lab session on the embedded simulators, through the CLI and the library.

Starts a simulated P3-DX (ARCOS over TCP on a free loopback port, 5x faster than real time),
then: the CLI's one-shot status, a square driven from Python, the wander example, a packet
dump and the round-trip benchmark with its C floor; then an IRB120 circle uploaded to the
embedded ABB simulator, monitored and validated (the time shift it reports is the download
time); then a simulated sensor hub with two concurrent `robocli subscribe` clients and a
summary read from Python; the wander is recorded to MCAP and drawn, the hub too. Takes
about 65 s. Everything it makes stays in OUT (default demo-out/ in the repository, which git
ignores) for you to open afterwards: the recordings (`robocli info`, Foxglove), the figures,
the arm's trajectory logs.
"""

from __future__ import annotations

import importlib.util
import math
import sys
import time
from pathlib import Path
from typing import Any

from robocli import Pioneer
from robocli.cli import main as robocli
from robocli.sim.pioneer.server import PioneerSim

#: Where the demo leaves its recordings, figures and logs (the first argument overrides it).
OUT = Path(__file__).resolve().parent.parent / "demo-out"
PLOT = importlib.util.find_spec("matplotlib") is not None
#: How long the wander runs (SIPs, 100 ms of robot time each): long enough to cross the room
#: and turn away from several walls (18 s of the demo's time at 5x).
WANDER_SIPS = 900
RECORD = importlib.util.find_spec("mcap") is not None

sys.path.insert(0, str(Path(__file__).resolve().parent))
from wander import wander  # noqa: E402


def step(title: str) -> None:
    print(f"\n=== {title}", flush=True)


def arm_circle(out: Path) -> int:
    """An IRB120 circle: generated, uploaded to the embedded ABB simulator with its state
    stream recorded, validated (per-joint RMSE), plotted when matplotlib is installed."""
    sim_log, real_log = str(out / "sim.json"), str(out / "real.json")
    figure = out / "arm_circle.png"
    steps = [
        ["traj", "circle", "--count", "100", "--output", sim_log, "--overwrite"],
        ["upload", "arm", "sim", "--file", sim_log, "--output", real_log, "--overwrite"],
        ["validate", sim_log, real_log, *(["--plot", str(figure), "--overwrite"] if PLOT else [])],
    ]
    for argv in steps:
        step("robocli " + " ".join(argv))
        if robocli(argv) != 0:
            return 1
    explain_delay(sim_log, real_log)
    print(f"plot written: {figure}" if PLOT else
          "no plot: matplotlib is not installed (pip install 'robocli-robots[plot]')")  # fmt: skip
    return 0


def explain_delay(sim_log: str, real_log: str) -> None:
    """Say what validate's delay is: not a lag of the simulator (it executes exactly), but
    the download, which the recording spans."""
    from robocli.kinematics.trajlog import read_log
    from robocli.kinematics.validate import validate

    delay_ms = validate(read_log(sim_log), read_log(real_log)).delay_s * 1e3
    print(
        f"the time shift, {delay_ms:.0f} ms, is the download: `upload --output` starts\n"
        "recording, then sends the 100 points, one round trip each, and the controller\n"
        "starts the circle when the last one (-3) is acknowledged. The simulator adds no\n"
        "lag of its own; a loaded machine makes the download, and so the shift, longer."
    )


def sensor_hub() -> int:
    """A simulated sensor hub (ros4mat v3 on a free loopback port): two `robocli subscribe adc`
    processes at once, each with its own cursor, then the IMU and ADC read from Python."""
    import subprocess

    from robocli import Hub
    from robocli.hub_server import HubServer

    with HubServer(bind="127.0.0.1", port=0, sim=True).start() as hub:
        where = f"127.0.0.1:{hub.port}"
        step(f"robocli serve --sim (in-process, on {where}); two subscribers at once")
        argv = ["subscribe", "adc", "--rate", "100", "--hub", where, "--duration", "2",
                "--format", "csv"]  # fmt: skip
        procs = [
            subprocess.Popen([sys.executable, "-m", "robocli", *argv], stdout=subprocess.PIPE,
                             text=True)
            for _ in range(2)
        ]  # fmt: skip
        for i, proc in enumerate(procs, 1):
            out, _ = proc.communicate(timeout=30)
            rows = out.splitlines()[1:]
            if proc.returncode != 0 or not rows:
                return 1
            print(f"robocli {' '.join(argv)}  # subscriber {i}: {len(rows)} rows, "
                  f"last: {rows[-1][:60]}")  # fmt: skip

        step("Python: Hub.connect, subscribe IMU at 200 Hz and ADC at 100 Hz, read 1 s")
        with Hub.connect("127.0.0.1", hub.port) as client:
            client.subscribe("imu", rate=200)
            client.subscribe("adc", rate=100)
            time.sleep(1.0)
            imu, adc = client.read("imu"), client.read("adc")
            accel = imu.accel
            print(f"imu: {imu.data.shape[1]} samples, mean accel z {accel[2].mean():+.2f} g; "
                  f"adc: {adc.data.shape} (channels x samples), "
                  f"hub clock offset {(client.clock_offset or 0.0) * 1e3:+.3f} ms")  # fmt: skip
    return 0


def recording(path: Path, robot: Pioneer) -> Any:
    """``Recorder(path)`` recording ``robot`` (pose, odom -> base_link, sonar and laser as
    Foxglove's schemas, every frame raw), or nothing without the record extra."""
    import contextlib

    if not RECORD:
        return contextlib.nullcontext()
    from robocli.io.record import Recorder

    rec = Recorder(path, overwrite=True)  # the demo replaces what it made last time
    rec.add(robot)
    return rec


def look(out: Path) -> int:
    """What was recorded: `robocli info`, `robocli plot`, and a hub recorded by the CLI."""
    if not RECORD:
        print(
            "no recordings: the record extra is not installed"
            " (pip install 'robocli-robots[record]')"
        )
        return 0
    wander_rec, hub_rec = str(out / "wander.mcap"), str(out / "hub.mcap")
    steps = [
        ["info", wander_rec],
        [
            "record",
            "--hub",
            "sim",
            "--sensors",
            "imu,adc:200",
            "-d",
            "2",
            "-o",
            hub_rec,
            "--overwrite",
        ],
    ]
    if PLOT:
        steps += [
            ["plot", wander_rec, "-c", "/pioneer/pose", "-c", "/pioneer/laser", "-o",
             str(out / "wander_path.png"), "--overwrite"],
            ["plot", hub_rec, "-c", "/hub/imu", "-c", "/hub/adc", "-f",
             "linear_acceleration.z", "-f", "channels.0", "-o", str(out / "hub.png"),
             "--overwrite"],
        ]  # fmt: skip
    for argv in steps:
        step("robocli " + " ".join(argv))
        if robocli(argv) != 0:
            return 1
    return 0


def run(out: Path = OUT) -> int:
    out.mkdir(parents=True, exist_ok=True)
    with PioneerSim("p3dx", time_scale=5.0) as sim:
        url = sim.serve_tcp("127.0.0.1", 0)
        step(f"robocli sim: a P3-DX on {url}")

        step(f"robocli connect pioneer {url} --once")
        if robocli(["connect", "pioneer", url, "--once"]) != 0:
            return 1

        step("Python: drive a 1 m square, compare odometry with the simulator's truth")
        with Pioneer.connect(url) as robot:
            robot.set_max_velocity(0.5, math.radians(90))
            robot.turn(0)
            x0, y0, _ = robot.pose
            for corner in range(4):
                robot.enable_motors()
                robot.move(1.0)
                sim.wait_until(lambda s: s.trans_vel > 0.01, timeout=5)
                sim.wait_until(lambda s: abs(s.trans_vel) < 1e-6, timeout=20)
                robot.turn(math.pi / 2)
                sim.wait_until(lambda s: abs(s.rot_vel) > 0.01, timeout=5)
                sim.wait_until(lambda s: abs(s.rot_vel) < 1e-6, timeout=20)
                robot.wait_for_sip()
                x, y, th = robot.pose
                print(
                    f"corner {corner + 1}: odometry x {x - x0:+.3f} m  y {y - y0:+.3f} m  "
                    f"th {math.degrees(th):+6.1f} deg"
                )
            truth = sim.snapshot()
            print(
                f"simulator truth:  x {truth.x:+.3f} m  y {truth.y:+.3f} m  "
                f"th {math.degrees(truth.th):+6.1f} deg"
            )
            robot.sim.start_laser()  # the simulated SICK LMS200: a 181-reading scan every SIP
            near = robot.sim.wait_for_laser(timeout=5).nearest()
            print(f"laser: nearest return {near[0]:.2f} m at {math.degrees(near[1]):+.0f} deg"
                  if near else "laser: no return within 32 m")  # fmt: skip

            where = f", recorded to {out / 'wander.mcap'}" if RECORD else ""
            step(
                f"examples/wander.py: the robot explores the room for {WANDER_SIPS // 10} s of "
                f"simulated time, turning away from what its sonar and laser see{where}"
            )
            with recording(out / "wander.mcap", robot):
                result = wander(robot, WANDER_SIPS)
            print(
                f"travelled {result.distance:.2f} m, {result.turns} turns away from walls, "
                f"{result.bumps} bumps; link: {robot.stats.sips} SIPs, "
                f"{robot.stats.bad_checksums} bad checksums"
            )

        step(f"robocli dump pioneer {url} --count 12")
        if robocli(["dump", "pioneer", url, "--count", "12"]) != 0:
            return 1

        step(f"robocli bench rtt {url} --count 300")
        if robocli(["bench", "rtt", url, "--count", "300"]) != 0:
            return 1
    if arm_circle(out) != 0 or sensor_hub() != 0 or look(out) != 0:
        return 1
    step("done: every command above also works on a real robot (a serial port or tcp://host:port)")
    shown = out.relative_to(Path.cwd()) if out.is_relative_to(Path.cwd()) else out
    print(f"what the demo made is in {shown}/ (kept):")
    for path in sorted(out.iterdir()):
        print(f"  {shown / path.name}")
    if RECORD:
        print(
            f"look again: robocli info {shown / 'wander.mcap'}; open the .mcap files in "
            "Foxglove (Open local file): the 3D panel shows the path, the laser and, once\n"
            "/robot_description is ticked in its topics, the P3-DX (docs/models.md)"
        )
    return 0


if __name__ == "__main__":
    sys.exit(run(Path(sys.argv[1]) if len(sys.argv) > 1 else OUT))
