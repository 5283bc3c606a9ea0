"""robocli.devices.arm.jobs as a notebook user calls it: a shape run to its end on the
built-in simulator, its joint log kept, the state stream recorded (real loopback sockets)."""

from __future__ import annotations

from pathlib import Path

import pytest

from robocli.devices.arm import Arm
from robocli.devices.arm.jobs import (
    KeptLog,
    arm_address,
    record_states,
    run_trajectory,
    shape_trajectory,
)
from robocli.errors import InvalidArgument
from robocli.io.record.upload import upload_recorder
from robocli.kinematics.trajlog import read_log


def test_a_circle_runs_to_its_end_and_its_log_is_kept(tmp_path: Path) -> None:
    said: list[str] = []
    ticks: list[tuple[int, int]] = []
    traj = shape_trajectory("irb120", "circle", 20, radius=0.02, duration=1.0)
    with arm_address("sim") as (host, motion, state):
        with Arm.connect(host, motion, state) as arm:
            kept = KeptLog(arm, tmp_path / "real.json")
            sent = run_trajectory(arm, traj, kept=kept, say=said.append,
                                  progress=lambda: _collect(ticks))  # fmt: skip
    assert sent == 20 and ticks[-1] == (20, 20)
    assert said == ["moving to the first point"]  # the work pose is not the circle's start
    assert kept.written is not None and kept.error is None
    assert len(read_log(tmp_path / "real.json")) == len(kept.written) >= 2


def test_a_log_that_cannot_be_written_says_why_when_the_block_failed(tmp_path: Path) -> None:
    (tmp_path / "real.json").write_text("the user's")
    with Arm.connect("sim://") as arm:
        kept = KeptLog(arm, tmp_path / "real.json")  # no overwrite: refused
        with pytest.raises(KeyError), kept:
            arm.wait_for_state()
            raise KeyError("the block's own error goes on")
    assert kept.written is None and kept.error is not None
    assert (tmp_path / "real.json").read_text() == "the user's"


def test_record_states_stops_at_the_count(tmp_path: Path) -> None:
    with Arm.connect("sim://") as arm, KeptLog(arm, tmp_path / "m.csv") as rec:
        record_states(arm, rec, count=5, timeout=5.0)
        assert len(rec.samples) >= 5


def test_shapes_and_the_upload_recorder(tmp_path: Path) -> None:
    assert len(shape_trajectory("irb120", "rectangle", 40, duration=2.0)) == 40
    with pytest.raises(InvalidArgument):
        shape_trajectory("irb120", "star")
    rec, listeners = upload_recorder(tmp_path / "up.mcap")
    assert set(listeners) == {"motion", "state"}
    rec.close()  # never begun: no file made
    assert not (tmp_path / "up.mcap").exists()


class _collect:
    def __init__(self, into: list[tuple[int, int]]) -> None:
        self.into = into

    def __enter__(self) -> object:
        return lambda done, total: self.into.append((done, total))

    def __exit__(self, *exc: object) -> None:
        return None
