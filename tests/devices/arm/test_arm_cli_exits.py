"""The arm commands' ways out against the built-in ABB simulator over real sockets: what
``--wait`` means, output paths checked before anything moves, busy ports, interrupts, pipes,
and the messages and exit codes of each."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from robocli.cli import main
from robocli.kinematics import load_model
from robocli.kinematics.trajectory import circle
from tests.commands.helpers import ctrl_c

IRB = load_model("irb120")


def run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def ports(motion: int, state: int) -> list[str]:
    return ["127.0.0.1", "--motion-port", str(motion), "--state-port", str(state)]


def test_wait_0_leaves_the_trajectory_running(make_sim, capsys) -> None:
    """``--wait 0`` is fire and forget: no STOP follows the activation, the arm runs the
    whole trajectory, and the message does not call it idle."""
    sim, mp, sp = make_sim(time_scale=4.0)
    code, out, err = run(capsys, "upload", "arm", *ports(mp, sp), "--shape", "circle",
                         "--wait", "0")  # fmt: skip
    assert code == 0, err
    assert "uploaded 100 points; the arm is moving, not waiting" in out
    assert "idle" not in out
    snap = sim.wait_until(lambda s: not s.in_motion, 30)  # activated before the reply to -3
    assert snap.stops == 0 and snap.trajectories == 2  # the approach, then the circle
    assert np.allclose(snap.joints, circle(IRB, 100).positions[-1], atol=1e-6)


def test_wait_with_monitor_needs_time(make_sim, tmp_path: Path, capsys) -> None:
    sim, mp, sp = make_sim()
    code, _, err = run(capsys, "upload", "arm", *ports(mp, sp), "--shape", "circle", "--wait",
                       "0", "--output", str(tmp_path / "r.json"))  # fmt: skip
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert sim.snapshot().motion_accepted == 0


def test_a_short_wait_says_the_arm_keeps_moving(make_sim, capsys) -> None:
    """``--wait`` bounds the waiting, not the motion: exit 1 (the controller answers), the
    trajectory is not stopped."""
    sim, mp, sp = make_sim(time_scale=1.0)
    code, out, err = run(
        capsys,
        "upload",
        "arm",
        *ports(mp, sp),
        "--shape",
        "circle",
        "--duration",
        "60",
        "--wait",
        "1",
    )  # fmt: skip (moving long after)
    assert code == 1, err
    assert "still moving after 1 s and keeps moving" in err
    assert len(err.strip().splitlines()) == 1 and "idle" not in out
    assert sim.snapshot().in_motion and sim.snapshot().stops == 0


@pytest.mark.parametrize("where", ["suffix", "nodir", "dir"])
def test_monitor_output_checked_before_recording(where: str, make_sim, tmp_path: Path,
                                                 capsys) -> None:  # fmt: skip
    sim, mp, sp = make_sim()
    out = {"suffix": tmp_path / "m.txt", "nodir": tmp_path / "no" / "m.json",
           "dir": tmp_path}[where]  # fmt: skip
    code, _, err = run(capsys, "monitor", "arm", "127.0.0.1", "--state-port", str(sp),
                       "--duration", "4", "-o", str(out))  # fmt: skip
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert sim.snapshot().state_accepted == 0  # refused before connecting, not after 4 s


def test_upload_monitor_path_checked_before_moving(make_sim, tmp_path: Path, capsys) -> None:
    sim, mp, sp = make_sim()
    code, _, err = run(capsys, "upload", "arm", *ports(mp, sp), "--shape", "circle",
                       "--output", str(tmp_path / "nonexistent" / "r.json"))  # fmt: skip
    assert code == 2 and "cannot write" in err, err
    snap = sim.snapshot()
    assert snap.points_received == 0 and snap.motion_accepted == 0


def test_a_busy_motion_port_exits_4_with_the_reason(make_sim, make_arm, capsys) -> None:
    """As ``dump arm --ports motion`` holding the motion port: the uploader is told the
    robot is busy (exit 4), as for a busy state port, and nothing is sent."""
    from robocli.devices.arm import Arm
    from robocli.errors import DeviceError

    sim, mp, sp = make_sim()
    make_arm(mp, sp, state=False, stop_on_failure=False)
    sim.wait_until(lambda s: s.motion_clients == 1, 30)
    code, out, err = run(capsys, "upload", "arm", *ports(mp, sp), "--shape", "circle")
    assert code == 4, err
    assert len(err.strip().splitlines()) == 1 and "robot busy" in err and f":{mp}" in err
    with pytest.raises(DeviceError, match="robot busy"):
        Arm.connect("127.0.0.1", mp, sp, state=False)
    assert sim.snapshot().points_received == 0


CONNECT = [sys.executable, "-m", "robocli", "connect", "arm"]


def _decimals(value: object) -> int:
    if isinstance(value, float):
        return len(repr(value).partition(".")[2])
    if isinstance(value, dict):
        return max((_decimals(v) for v in value.values()), default=0)
    if isinstance(value, list):
        return max((_decimals(v) for v in value), default=0)
    return 0


def test_connect_json_is_rounded(capsys) -> None:
    """JSON carries the float32 resolution of Simple Message reals, not float noise."""
    code, out, err = run(capsys, "connect", "arm", "sim", "--once", "--json")
    assert code == 0, err
    state = json.loads(out)
    assert _decimals(state) <= 6
    assert state["joints_rad"] == pytest.approx(list(IRB.work), abs=1e-6)


def test_connect_into_a_closed_pipe_ends_quietly(make_sim) -> None:
    sim, mp, sp = make_sim()
    proc = subprocess.Popen([*CONNECT, "127.0.0.1", "--state-port", str(sp), "--json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.readline()
    proc.stdout.readline()
    proc.stdout.close()  # like `| head -2`
    assert proc.wait(20) == 0
    assert proc.stderr.read() == b""


def test_connect_ctrl_c_exits_130(make_sim) -> None:
    sim, mp, sp = make_sim()
    proc = subprocess.Popen([*CONNECT, "127.0.0.1", "--state-port", str(sp), "--json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    assert proc.stdout is not None
    proc.stdout.readline()  # it runs
    _, err = ctrl_c(proc, 20)
    assert proc.returncode == 130
    assert err.splitlines() == ["robocli: interrupted"]


def test_streaming_to_an_abb_fails_when_nothing_moved(make_sim, tmp_path: Path,
                                                      capsys) -> None:  # fmt: skip
    """An ABB acknowledges streamed points but never runs them without -3: once their
    durations have elapsed without motion, the upload fails and says to drop --stream."""
    from robocli.devices.arm import Arm
    from robocli.errors import DeviceError

    sim, mp, sp = make_sim(time_scale=1.0)
    sim_json = tmp_path / "sim.json"
    assert run(capsys, "traj", "circle", "--count", "20", "--duration", "1", "--output",
               str(sim_json))[0] == 0  # fmt: skip
    code, out, err = run(capsys, "upload", "arm", *ports(mp, sp), "--stream", "--file",
                         str(sim_json))  # fmt: skip
    assert code == 4, err
    assert "did not move" in err and "--stream" in err and len(err.strip().splitlines()) == 1
    assert "idle" not in out
    snap = sim.snapshot()
    assert snap.trajectories == 0 and np.allclose(snap.joints, IRB.work, atol=1e-6)
    # one client per port: the CLI's closed, but the controller may not have seen it yet
    sim.wait_until(lambda s: s.motion_clients == 0 and s.state_clients == 0, 30)
    with Arm.connect("127.0.0.1", mp, sp) as arm:  # the library says the same
        arm.wait_for_state()
        arm.stream(circle(IRB, 10, duration=0.5), first_duration=0.2)
        with pytest.raises(DeviceError, match="did not move"):
            arm.wait_until_idle(20)


def test_a_refused_connection_names_the_arm_simulator(capsys) -> None:
    import socket

    with socket.socket() as s:  # a free port nobody listens on
        s.bind(("127.0.0.1", 0))
        free = s.getsockname()[1]
    code, _, err = run(capsys, "connect", "arm", "127.0.0.1", "--state-port", str(free))
    assert code == 3 and len(err.strip().splitlines()) == 1, err
    assert "connection refused" in err and "robocli sim abb" in err and "pioneer" not in err


def test_monitor_duration_is_at_least_a_few_states(make_sim, tmp_path: Path, capsys) -> None:
    sim, mp, sp = make_sim()
    code, _, err = run(capsys, "monitor", "arm", "127.0.0.1", "--state-port", str(sp),
                       "--duration", "0.01", "-o", str(tmp_path / "m.json"))  # fmt: skip
    assert code == 2 and "--duration" in err and len(err.strip().splitlines()) == 1, err


def test_a_recording_of_one_sample_is_a_failure_not_unreachable(make_sim, make_arm) -> None:
    from robocli.devices.arm import TooFewSamples
    from robocli.errors import EXIT_FAILURE

    sim, mp, sp = make_sim(state_ms=5000.0)
    arm = make_arm(mp, sp, state=True, motion=False)
    rec = arm.record()
    rec.stop()
    with pytest.raises(TooFewSamples, match="a log needs two") as info:
        rec.log()
    assert info.value.exit_code == EXIT_FAILURE
