"""``monitor arm`` and ``upload --monitor`` write what they recorded on every ending (issue
14): Ctrl-C and SIGTERM (exit 130), a ``--wait`` that runs out (exit 1) and a lost link
(exit 1) each leave a readable log holding the samples, said on stderr. Before, each of
these endings but monitor's Ctrl-C threw the whole recording away.

``robocli`` runs as a process against the simulator in this process, which says when the
recording has samples (states sent) and which closes for a lost link. The simulator stamps
its states (JOINT_FEEDBACK), so every state the client read is a sample of the log; how
many it had read when the ending came is the machine's scheduling, so a log is asked to
hold two samples (what a log needs), not a number of them.
"""

from __future__ import annotations

import signal
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest

from robocli.kinematics.trajlog import read_log
from robocli.sim.abb.server import AbbSim, ArmSimState

TIMEOUT = 30.0
STATE_S = 0.005  #: the simulator's state period
ROBOCLI = [sys.executable, "-m", "robocli"]


@pytest.fixture
def sim() -> Iterator[tuple[AbbSim, str, str]]:
    """An exact simulator, a stamped state every 5 ms: (simulator, motion port, state port)."""
    with AbbSim(state_ms=STATE_S * 1e3, feedback=True) as simulator:
        motion, state = simulator.serve_tcp("127.0.0.1", 0, 0)
        yield simulator, motion.rsplit(":", 1)[1], state.rsplit(":", 1)[1]


def _run(args: list[str], sim: AbbSim, ready: Callable[[ArmSimState], bool],
         ending: str) -> tuple[int, str]:  # fmt: skip
    """Run ``robocli ARGS``; once ``ready`` holds and 100 more states went out, end it by
    ``ending`` (SIGINT, SIGTERM, lost: the simulator closes; wait: by itself). Returns the
    exit code and stderr."""
    proc = subprocess.Popen([*ROBOCLI, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            stdin=subprocess.DEVNULL, text=True)  # fmt: skip
    try:
        if ending != "wait":
            sent = sim.wait_until(ready, TIMEOUT).states_sent
            sim.wait_until(lambda s: s.states_sent >= sent + 100, TIMEOUT)  # 0.5 s of states
            if ending == "lost":
                sim.close()
            else:
                proc.send_signal(signal.SIGINT if ending == "SIGINT" else signal.SIGTERM)
        _, err = proc.communicate(timeout=2 * TIMEOUT)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(TIMEOUT)
    return proc.returncode, err


def _check(out: Path, code: int, err: str, expected: int) -> None:
    assert code == expected, err
    log = read_log(out)  # written, and readable
    assert len(log) >= 2, (len(log), err)
    # every state from the first sample to the last is in the log (on the controller's
    # clock, float32 on the wire: a state every 5 ms, and the instants a motion starts and ends)
    steps = np.diff(log.time)
    assert steps.min() > 0 and steps.max() < STATE_S + 1e-3, steps.max()
    said = [line for line in err.splitlines() if line.startswith("recorded ")]
    assert said == [f"recorded {len(log)} samples over {log.time[-1] - log.time[0]:.3f} s "
                    f"-> {out}"], err  # fmt: skip
    assert "Traceback" not in err


@pytest.mark.parametrize(("ending", "code"), [("SIGINT", 130), ("SIGTERM", 130), ("lost", 1)])
def test_monitor_keeps_its_log(sim: tuple[AbbSim, str, str], tmp_path: Path, ending: str,
                               code: int) -> None:  # fmt: skip
    simulator, _, state_port = sim
    out = tmp_path / "m.json"
    got, err = _run(["monitor", "arm", "127.0.0.1", "--state-port", state_port,
                     "--duration", "600", "-o", str(out)],
                    simulator, lambda s: s.state_accepted > 0, ending)  # fmt: skip
    _check(out, got, err, code)


def test_monitor_records_until_ctrl_c_without_samples_or_duration(
    sim: tuple[AbbSim, str, str], tmp_path: Path
) -> None:
    simulator, _, state_port = sim
    out = tmp_path / "m.csv"
    got, err = _run(["monitor", "arm", "127.0.0.1", "--state-port", state_port, "-o", str(out)],
                    simulator, lambda s: s.state_accepted > 0, "SIGINT")  # fmt: skip
    _check(out, got, err, 130)
    assert f"recording to {out} until Ctrl-C" in err


@pytest.mark.parametrize(
    ("ending", "code"), [("SIGINT", 130), ("SIGTERM", 130), ("lost", 1), ("wait", 1)]
)
def test_upload_monitor_keeps_its_log(sim: tuple[AbbSim, str, str], tmp_path: Path,
                                      ending: str, code: int) -> None:  # fmt: skip
    """A 20 s circle, ended while the arm moves (--wait 1: after a second of waiting)."""
    simulator, motion_port, state_port = sim
    out = tmp_path / "r.json"
    wait = ["--wait", "1"] if ending == "wait" else []
    got, err = _run(["upload", "arm", "127.0.0.1", "--motion-port", motion_port,
                     "--state-port", state_port, "--shape", "circle", "--duration", "20",
                     "--output", str(out), *wait],
                    simulator, lambda s: s.points_received >= 100 and s.in_motion,
                    ending)  # fmt: skip
    _check(out, got, err, code)
    if ending == "wait":
        assert "still moving after 1 s" in err
