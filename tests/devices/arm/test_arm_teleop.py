"""Arm teleop logic against the real simulator over sockets: jogs move the right joint the
right way within limits, release and close send STOP, a joint at its limit is refused."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from typing import Any

import numpy as np
import pytest

from robocli.devices.arm.teleop import ArmTeleop, Jog, JogKeys, jog_target, run_arm_teleop
from robocli.errors import ConnectionLost, TimeoutError
from robocli.kinematics import LimitError, fk, load_model
from tests.commands.helpers import ROBOCLI
from tests.commands.test_screens import terminal
from tests.waiting import wait_for

IRB120 = load_model("irb120")


def hold(teleop: ArmTeleop, key: str, seconds: float) -> None:
    """Press ``key`` repeatedly (like a terminal's auto-repeat) for ``seconds``."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        teleop.key(key)
        teleop.step()
        time.sleep(0.02)


def release(teleop: ArmTeleop, timeout: float = 5.0) -> None:
    """Step without keys until the release timeout sent STOP."""
    stops = teleop.sent["stops"]
    wait_for(lambda: teleop.step() or teleop.sent["stops"] != stops,
             "a STOP after the key was released", timeout=timeout)  # fmt: skip


def test_keys_release_and_modes() -> None:
    keys = JogKeys(6, release_timeout=0.4)
    keys.key("3", 0.0)
    keys.key("up", 0.0)
    assert keys.jog(0.3) == Jog("joint", 2, 1)
    assert keys.jog(0.5) is None  # no key-up from terminals: the timeout releases it
    keys.key("c", 1.0)
    keys.key("f", 1.0)
    assert keys.jog(1.1) == Jog("cartesian", 2, -1)
    keys.key("space", 1.2)
    assert keys.jog(1.2) is None
    keys.key("9", 1.3)  # no joint 9: ignored
    assert keys.mode == "cartesian"
    keys.key("+", 1.3)
    assert keys.scale > 1
    keys.key("q", 1.4)
    assert keys.quit and keys.jog(1.4) is None


def test_jog_target_clips_and_refuses_at_limits() -> None:
    q = IRB120.work.copy()
    hi = IRB120.limits[0, 1]
    q[0] = hi - 0.01
    target, _ = jog_target(IRB120, q, Jog("joint", 0, 1), 0.3, 0.5, 0.05)
    assert target[0] == pytest.approx(hi) and np.allclose(target[1:], q[1:])
    with pytest.raises(LimitError, match="joint 1 is at its upper limit"):
        jog_target(IRB120, target, Jog("joint", 0, 1), 0.3, 0.5, 0.05)
    back, _ = jog_target(IRB120, target, Jog("joint", 0, -1), 0.3, 0.5, 0.05)
    assert back[0] < hi
    up, duration = jog_target(IRB120, IRB120.work, Jog("cartesian", 2, 1), 0.2, 0.5, 0.05)
    dz = fk(IRB120, up)[0][:3, 3] - fk(IRB120, IRB120.work)[0][:3, 3]
    assert dz == pytest.approx([0, 0, 0.01], abs=1e-6) and duration >= 0.2


@pytest.mark.parametrize("profile", ["abb", "generic"])
def test_jog_moves_the_joint_and_release_stops(make_sim: Any, make_arm: Any,
                                               profile: str) -> None:  # fmt: skip
    sim, mp, sp = make_sim(profile=profile, time_scale=2.0)
    arm = make_arm(mp, sp)
    arm.wait_for_state()
    before = sim.snapshot()
    teleop = ArmTeleop(arm, stream=profile == "generic", joint_speed=0.2)
    teleop.key("2")
    hold(teleop, "s", 0.5)  # J2 minus
    moved = sim.snapshot()
    assert moved.joints[1] < before.joints[1] - 0.02
    assert np.allclose(moved.joints[2:], before.joints[2:], atol=1e-9)  # only J2 moves
    release(teleop)
    assert sim.snapshot().stops == before.stops + 1
    still = sim.wait_until(lambda s: not s.in_motion, 30).joints
    time.sleep(0.05)
    assert sim.snapshot().joints == still  # stopped where it was
    teleop.close()  # quitting sends STOP too
    assert sim.wait_until(lambda s: s.stops == before.stops + 2, 30)


def test_joint_at_limit_is_refused(make_sim: Any, make_arm: Any) -> None:
    q0 = IRB120.work.copy()
    q0[0] = IRB120.limits[0, 0]  # joint 1 at its lower limit
    sim, mp, sp = make_sim(q0=q0)
    arm = make_arm(mp, sp)
    arm.wait_for_state()
    with ArmTeleop(arm) as teleop:
        teleop.key("1")
        hold(teleop, "a", 0.3)  # towards the limit
        assert "joint 1 is at its lower limit" in teleop.message
        assert sim.snapshot().trajectories == 0 and teleop.sent["points"] == 0
        hold(teleop, "d", 0.3)  # away from it
        assert teleop.message == ""
        assert sim.wait_until(lambda s: s.joints[0] > q0[0] + 1e-3, 30)
        assert teleop.sent["trajectories"] > 0


def test_cartesian_jog_moves_the_tcp(make_sim: Any, make_arm: Any) -> None:
    sim, mp, sp = make_sim()
    arm = make_arm(mp, sp)
    arm.wait_for_state()
    start = fk(IRB120, list(sim.snapshot().joints))[0][:3, 3]
    with ArmTeleop(arm, cart_speed=0.1) as teleop:
        teleop.key("c")
        hold(teleop, "r", 0.4)  # +z
        assert "TCP" in teleop.status()
    end = fk(IRB120, list(sim.wait_until(lambda s: not s.in_motion, 30).joints))[0][:3, 3]
    assert end[2] > start[2] + 0.005
    assert np.allclose(end[:2], start[:2], atol=2e-3)


def test_run_loop_stops_on_quit_and_on_a_lost_link(make_sim: Any, make_arm: Any) -> None:
    sim, mp, sp = make_sim()
    arm = make_arm(mp, sp)
    arm.wait_for_state()
    keys = iter(["2", "w", "w", None, "q"])
    # the loop's own clock, 20 ms a key: the second press and the pause fall within the jog
    # period, however long the machine takes over each step (one trajectory, then quit)
    now = [time.monotonic()]

    def read_key(timeout: float) -> str | None:
        now[0] += 0.02
        return next(keys, "q")

    teleop = ArmTeleop(arm, stale=3600.0, clock=lambda: now[0])
    run_arm_teleop(teleop, read_key)
    assert teleop.quit and teleop.sent["trajectories"] == 1
    assert sim.wait_until(lambda s: s.stops == teleop.sent["stops"] >= 1, 30).trajectories == 1
    # the state link dies while a key is held: the teleop stops the arm and says why
    teleop = ArmTeleop(arm, stale=0.3)
    teleop.key("2")
    sim.close()
    with pytest.raises((TimeoutError, ConnectionLost)):  # stale after 0.3 s: the hold ends
        hold(teleop, "w", 60.0)


def test_cli_needs_a_terminal() -> None:
    done = subprocess.run([*ROBOCLI, "teleop", "arm", "sim"], stdin=subprocess.DEVNULL,
                          capture_output=True, text=True, timeout=30)  # fmt: skip
    assert done.returncode == 2 and len(done.stderr.splitlines()) == 1
    assert "interactive terminal" in done.stderr


def test_cli_jogs_on_a_terminal_and_quits() -> None:
    with terminal("teleop", "arm", "sim", "--stale", "30") as term:  # see the next test
        term.read_until(b"q or Ctrl-C quits")
        term.read_until(b"\rJ1  idle", count=2)  # the status line redraws while idle
        os.write(term.master, b"2")
        for _ in range(10):
            os.write(term.master, b"w")
            term.drain(0.03)
        term.read_until(b"J2  J2+")
        os.write(term.master, b"q")
        code, err = term.finish()
    assert code == 0 and err == "", err
    status = term.text.rstrip().rsplit("\r", 1)[-1]
    assert len(status) <= 80 and "tcp" in status
    assert term.output.endswith(b"\n")


def test_cli_ctrl_c_exits_130_with_one_line() -> None:
    with terminal("teleop", "arm", "sim") as term:
        term.read_until(b"\rJ1  idle")
        term.proc.send_signal(signal.SIGINT)
        code, err = term.finish()
    assert code == 130 and err.splitlines() == ["robocli: interrupted"], err


def _j2(status: str) -> float:
    """Joint 2 (deg) on a status line: ``J2  J2+  x1    deg +0.0 +10.0 ...``."""
    return float(status.split(" deg ", 1)[1].split()[1])


def test_cli_streams_to_an_embedded_streaming_simulator() -> None:
    """``teleop arm sim --stream`` starts the generic (streaming) profile itself: the jog
    moves the arm (an ABB profile would buffer the streamed points and never run them)."""
    # the embedded simulator shares the process: --stale so that a loaded machine's pause
    # in its state stream is not the end of the jog this test is about
    with terminal("teleop", "arm", "sim", "--stream", "--stale", "30") as term:
        term.read_until(b"(streaming)")
        term.read_until(b"\rJ1  idle", count=2)
        before = _j2(term.text.rsplit("\r", 1)[-1])
        os.write(term.master, b"2")
        for _ in range(15):
            os.write(term.master, b"w")
            term.drain(0.03)
        term.read_until(b"\rJ2  idle")  # released: STOP sent
        os.write(term.master, b"q")
        code, err = term.finish()
    assert code == 0 and err == "", err
    lines = [x for x in term.text.split("\r") if " deg " in x]
    assert max(_j2(x) for x in lines) > before + 0.5


def test_run_loop_ends_on_a_link_lost_while_idle(make_sim: Any, make_arm: Any) -> None:
    """No key held, nothing sent: the loop still notices the controller went away."""
    sim, mp, sp = make_sim()
    arm = make_arm(mp, sp)
    arm.wait_for_state()
    teleop = ArmTeleop(arm)
    deadline = time.monotonic() + 10.0

    def read_key(timeout: float) -> str | None:  # no key; quits after 10 s at most
        time.sleep(timeout)
        return "q" if time.monotonic() > deadline else None

    sim.close()
    with pytest.raises(ConnectionLost):
        run_arm_teleop(teleop, read_key)


def test_cli_says_in_one_line_that_the_controller_went_away(make_sim: Any) -> None:
    sim, mp, sp = make_sim()
    with terminal("teleop", "arm", "127.0.0.1", "--motion-port", str(mp), "--state-port",
                  str(sp)) as term:  # fmt: skip
        term.read_until(b"\rJ1  idle")
        sim.close()
        code, err = term.finish()
    assert code == 1 and len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert f":{sp}" in err or f":{mp}" in err
