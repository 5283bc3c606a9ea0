"""The lab in network namespaces (robocli.bench.lab): a 1-robot 1-laptop lab, a laptop's
``robocli subscribe adc`` printing the rows of the hub in the robot's namespace, and every
namespace removed on every ending. Root and iproute2 only: skipped with the reason
otherwise."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from robocli.bench.lab.netns import Lab, LabError, run, unavailable_reason, wait_for

REASON = unavailable_reason()
pytestmark = [pytest.mark.netns, pytest.mark.skipif(REASON is not None, reason=REASON or "")]

DEADLINE_S = 30.0  # bounds a failure only


def namespaces(prefix: str) -> list[str]:
    out = run("ip", "netns", "list", check=False)
    return [line.split()[0] for line in out.splitlines() if line.startswith(prefix + "-")]


def start_hub(lab: Lab) -> str:
    robot = lab.robot(0)
    hub = lab.spawn(robot, [sys.executable, "-m", "robocli", "serve", "--sim", "--bind",
                            robot.address, "--port", "1500"], "hub0")  # fmt: skip
    wait_for(lambda: "hub serving" in hub.tail(), DEADLINE_S, "hub start", [hub])
    return f"{robot.address}:1500"


def test_laptop_subscribes_to_a_hub_in_another_namespace() -> None:
    with Lab(robots=1, laptops=1, prefix=f"rcl-{os.getpid()}-t") as lab:
        address = start_hub(lab)
        laptop = lab.laptop(0)
        cmd = ["ip", "netns", "exec", laptop.ns, sys.executable, "-m", "robocli", "subscribe"]
        cmd += ["adc", "--rate", "100", "--hub", address, "--count", "20", "--format", "csv"]
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=DEADLINE_S)
        assert done.returncode == 0, done.stderr
        rows = [line.split(",") for line in done.stdout.splitlines()]
        header, data = rows[0], rows[1:]
        assert header[0] == "t" and len(header) == 9  # time + 8 channels
        assert len(data) == 20
        assert all(len(r) == 9 for r in data)
        times = [float(r[0]) for r in data]
        assert times == sorted(times)
        # the hub is not reachable from the machine's own namespace: the lab is isolated
        assert address.split(":")[0] not in run("ip", "-br", "addr")
        # the robot's uplink carried them
        assert lab.tx_bytes(lab.robot(0)) > 20 * 8 * 2
    assert namespaces(lab.prefix) == []


def test_laptop_subscribes_over_zenoh_to_a_hub_in_another_namespace() -> None:
    pytest.importorskip("zenoh", reason="robocli-robots[zenoh] is not installed")
    with Lab(robots=1, laptops=1, prefix=f"rcl-{os.getpid()}-z") as lab:
        robot = lab.robot(0)
        endpoint = f"tcp/{robot.address}:7447"  # the hub listens there, the laptop connects
        hub = lab.spawn(robot, [sys.executable, "-m", "robocli", "serve", "--sim", "--zenoh",
                                endpoint, "--name", "r0", "--no-tcp"], "hub0")  # fmt: skip
        wait_for(lambda: "hub serving" in hub.tail(), DEADLINE_S, "hub start", [hub])
        cmd = ["ip", "netns", "exec", lab.laptop(0).ns, sys.executable, "-m", "robocli"]
        cmd += ["subscribe", "adc", "--rate", "100", "--zenoh", endpoint, "--hub", "r0"]
        cmd += ["--count", "20", "--format", "csv"]
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=DEADLINE_S)
        assert done.returncode == 0, done.stderr
        rows = [line.split(",") for line in done.stdout.splitlines()]
        assert rows[0][0] == "t" and len(rows[0]) == 9
        assert len(rows) == 21 and all(len(r) == 9 for r in rows[1:])
        times = [float(r[0]) for r in rows[1:]]
        assert times == sorted(times)
        assert lab.tx_bytes(robot) > 20 * 8 * 2  # over the robot's uplink
    assert namespaces(lab.prefix) == []


def test_every_namespace_goes_when_the_block_fails() -> None:
    prefix = f"rcl-{os.getpid()}-f"
    with pytest.raises(RuntimeError), Lab(robots=2, laptops=2, prefix=prefix) as lab:
        hub = lab.spawn(lab.robot(0), [sys.executable, "-c", "import time; time.sleep(600)"],
                        "sleeper")  # fmt: skip
        assert len(namespaces(prefix)) == 6  # bridge, server, 2 robots, 2 laptops
        raise RuntimeError("a failing test")
    assert namespaces(prefix) == []
    assert hub.popen.poll() is not None  # killed, not left behind


def test_a_lab_that_cannot_be_built_leaves_nothing_it_made() -> None:
    prefix = f"rcl-{os.getpid()}-x"
    taken = f"{prefix}-l0"  # someone else's namespace, in the way of the lab's laptop
    run("ip", "netns", "add", taken)
    try:
        with pytest.raises(LabError, match="l0"), Lab(robots=1, laptops=1, prefix=prefix):
            pass
        assert namespaces(prefix) == [taken]  # the lab's own are gone, the other one kept
    finally:
        run("ip", "netns", "del", taken, check=False)


@pytest.mark.parametrize("mode", ["tcp", "zenoh"])
def test_the_bench_counts_what_a_laptop_receives_over_the_robot_uplink(mode: str) -> None:
    from robocli.bench.lab.bench import run_lab

    if mode == "zenoh":
        pytest.importorskip("zenoh", reason="robocli-robots[zenoh] is not installed")
    r = run_lab(mode, robots=1, laptops=1, seconds=2.0, warmup=0.5)
    assert r.errors == []
    assert set(r.sensors) == {"imu", "adc", "camera"}
    for name in ("imu", "adc", "camera"):
        s = r.sensors[name]
        assert s["samples"] > 0 and s["duplicates"] == 0
        assert s["p99"] is not None and s["p99"] > 0  # received after acquired, one clock
    # the uplink carried what the laptop received (its window starts and ends a little later)
    payload = sum(s["bytes"] for s in r.sensors.values())
    assert r.uplink_bytes[0] >= payload * 0.8  # none around it (shared memory)
    assert len(r.hub_cores) == 1 and r.hub_cores[0] >= 0
    assert namespaces(f"rcl-{os.getpid()}") == []


def test_a_class_watches_the_pioneer_one_laptop_drives_and_killing_the_driver_stops_it() -> None:
    pytest.importorskip("zenoh", reason="robocli-robots[zenoh] is not installed")
    from robocli.bench.lab.pioneer import class_drives_pioneer

    r = class_drives_pioneer(laptops=3)  # laptop 0 drives, laptops 1 and 2 watch
    assert r.watchers_moving == 2
    assert len(r.stop_delays) == 2 and all(d > 0 for d in r.stop_delays)
    assert namespaces(f"rcl-{os.getpid()}") == []


def test_laptops_see_the_router_come_back_and_a_killed_hub_leave() -> None:
    pytest.importorskip("zenoh", reason="robocli-robots[zenoh] is not installed")
    from robocli.bench.lab.faults import fault_run

    r = fault_run(down_s=1.0)
    assert r.gap_s >= 1.0  # nothing came while the router was away
    assert r.back_s > 0  # and batches came again once it was back
    assert r.left_s is not None and r.left_s > 0  # the hub's liveliness token left
    assert namespaces(f"rcl-{os.getpid()}") == []
