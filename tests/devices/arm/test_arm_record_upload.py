"""Recording an arm while the CLI uploads to it, and ``record``'s arm options (issue 21,
point 11): an ABB takes one client per port, so ``upload --record`` records the upload's own
connection; ``record`` takes the same link options as the arm commands, parsed by the same
code, and names only options it has."""

from __future__ import annotations

import math
import struct
from pathlib import Path

import pytest
from mcap.reader import make_reader

from robocli.io.record import info
from robocli.io.record.reader import raw_frame
from robocli.protocols import simple_message as sm
from robocli.sim.abb.server import AbbSim
from tests.commands.helpers import one_line_error, run
from tests.devices.arm.conftest import port_of
from tests.io.readback import decoded


def _topics(path: Path) -> dict[str, list[bytes]]:
    out: dict[str, list[bytes]] = {}
    with path.open("rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
            data = bytes(message.data)
            if "/raw/" in channel.topic:  # a raw channel's frame, as its schema holds it
                data = raw_frame(channel.message_encoding, data)
            out.setdefault(channel.topic, []).append(data)
    return out


def _msg_type(frame: bytes, order: str = "<") -> int:
    return int(struct.unpack_from(order + "i", frame, 4)[0])


def test_upload_records_its_own_connection(tmp_path: Path) -> None:
    path = tmp_path / "upload.mcap"
    with AbbSim("irb120", state_ms=5.0, feedback=True) as sim:
        motion, state = (port_of(u) for u in sim.serve_tcp("127.0.0.1", 0, 0))
        # a second client on the state port is what `record --arm` beside an upload was
        proc = run("upload", "arm", "127.0.0.1", "--motion-port", str(motion), "--state-port",
                   str(state), "--shape", "circle", "--count", "20", "--record", str(path),
                   timeout=120)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert "recording to" in proc.stderr and "recorded" in proc.stderr
    summary = info(path)
    assert summary.summary and not summary.truncated
    topics = _topics(path)
    sent = [_msg_type(f) for f in topics["/arm/raw/motion/tx"]]
    assert (
        sent.count(sm.SimpleMessageType.JOINT_TRAJ_PT) >= 20
    )  # every point of the upload, and more
    assert topics["/arm/raw/motion/rx"] and topics["/arm/raw/state/rx"]
    assert topics["/arm/joint_states"] and topics["/arm/joint_feedback"]


def test_upload_record_is_checked_before_the_arm_moves(tmp_path: Path) -> None:
    bad = run("upload", "arm", "sim", "--shape", "circle", "--record", str(tmp_path / "x.txt"))
    assert "needs a .mcap name" in one_line_error(bad, 2)
    assert not (tmp_path / "x.txt").exists()


@pytest.mark.parametrize(("order", "real"), [(">", 8), ("<", 4)])
def test_record_takes_every_arm_link_option(tmp_path: Path, order: str, real: int) -> None:
    path = tmp_path / "arm.mcap"
    with AbbSim("irb120", state_ms=5.0, feedback=True, byteorder=order, real=real) as sim:
        _, state = sim.serve_tcp("127.0.0.1", 0, 0)
        proc = run("record", "--arm", "127.0.0.1", "--state-port", str(port_of(state)),
                   "--byte-order", "big" if order == ">" else "little", "--real-size", str(real),
                   "--robot", "irb120", "--timeout", "10", "-n", "40", "-o", str(path))  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    with path.open("rb") as f:
        joints = list(make_reader(f).iter_messages(topics=["/arm/joint_states"]))
    assert joints
    for item in joints:
        q = decoded(item)["position"]
        assert len(q) == 6 and all(math.isfinite(v) and abs(v) < 2 * math.pi for v in q)


def test_record_names_only_options_it_has(tmp_path: Path) -> None:
    helped = run("record", "-h").stdout
    for option in (
        "--motion-port",
        "--state-port",
        "--byte-order",
        "--real-size",
        "--robot",
        "--timeout",
    ):  # both ports, as every arm command (issue 22)
        assert option in helped
    bad = run("record", "--arm", "127.0.0.1:11002", "-o", str(tmp_path / "x.mcap"))
    line = one_line_error(bad, 2)
    assert "--state-port" in line and "--motion-port" in line
    wrong = run("record", "--arm", "sim", "--real-size", "5", "-o", str(tmp_path / "x.mcap"))
    assert wrong.returncode == 2 and "--real-size" in wrong.stderr
    assert not (tmp_path / "x.mcap").exists()
