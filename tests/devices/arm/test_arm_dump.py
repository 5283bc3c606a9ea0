"""``robocli dump arm`` as a user runs it (a subprocess): decoded Simple Messages of both
ports in time order, JSON Lines, a capture that ``--file`` and robocli.io read back, the
recorded traces in all three variants, ``| head`` and Ctrl-C, one-line errors."""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from robocli.io.capture import read_capture
from robocli.protocols import simple_message as sm
from tests import paths
from tests.commands.helpers import ctrl_c

DATA = paths.DATA / "simple_message"
CLI = [sys.executable, "-m", "robocli", "dump", "arm"]


def dump(*args: str, timeout: float = 30.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=timeout)


def test_live_json_lines_in_time_order() -> None:
    done = dump("sim", "--count", "9", "--json")
    assert done.returncode == 0, done.stderr
    records = [json.loads(line) for line in done.stdout.splitlines()]
    assert len(records) == 9 and done.stderr == ""
    assert {r["port"] for r in records} == {"state"} and {r["dir"] for r in records} == {"s2c"}
    assert [r["name"] for r in records[:2]] == ["JOINT_POSITION", "STATUS"]
    assert all(a["t"] <= b["t"] for a, b in zip(records, records[1:], strict=False))
    first = records[0]["fields"]
    assert len(first["joints"]) == 6 and first["joints"][1] == pytest.approx(0.174533)


def test_capture_is_read_back(tmp_path: Path) -> None:
    out = tmp_path / "arm.jsonl"
    done = dump("sim", "--count", "12", "--hex", "--output", str(out))
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert len(lines) == 24  # a text line and a hex line per message
    assert "<- JOINT_POSITION" in lines[0] and "seq=0 joints=[" in lines[0]
    frames = list(read_capture(out, "sm-le"))
    assert len(frames) == 12 and {f.direction for f in frames} == {"rx:state"}  # the port kept
    assert bytes.fromhex(lines[1].replace(" ", "")) == frames[0].frame
    names = [sm.decode(f.frame).msg_type.name for f in frames]  # type: ignore[union-attr]
    again = dump("--file", str(out), "--json")
    records = [json.loads(x) for x in again.stdout.splitlines()]
    assert [(r["name"], r["port"]) for r in records] == [(n, "state") for n in names]


def test_a_capture_keeps_motion_and_state_apart(tmp_path: Path) -> None:
    """Frames of both ports in one capture: ``--file`` says each one's port (``dump arm -o``
    dropped it, so motion and state traffic could not be told apart); a capture without
    ports (the traces, older captures) still reads, its port null."""
    from robocli.io.capture import CaptureWriter

    state_types = {
        sm.SimpleMessageType.JOINT_POSITION,
        sm.SimpleMessageType.STATUS,
        sm.SimpleMessageType.JOINT_FEEDBACK,
    }
    old = list(read_capture(DATA / "exchange_le.jsonl", "sm-le"))
    ports = []
    out = tmp_path / "both.jsonl"
    with CaptureWriter(out) as writer:
        for f in old:
            port = "state" if sm.decode(f.frame).msg_type in state_types else "motion"
            writer.write(f.t or 0.0, f.direction, f.frame, port)
            ports.append(port)
    assert {"motion", "state"} <= set(ports)
    done = dump("--file", str(out), "--json")
    assert done.returncode == 0, done.stderr
    assert [json.loads(x)["port"] for x in done.stdout.splitlines()] == ports
    text = dump("--file", str(out)).stdout.splitlines()
    assert [line.split()[1] for line in text] == ports
    before = dump("--file", str(DATA / "exchange_le.jsonl"), "--json")
    assert {json.loads(x)["port"] for x in before.stdout.splitlines()} == {None}


@pytest.mark.parametrize("variant,options", [
    ("le", []), ("bswap", ["--byte-order", "big"]), ("float64", ["--real-size", "8"]),
])  # fmt: skip
def test_traces_decode_in_every_variant(variant: str, options: list[str]) -> None:
    done = dump("--file", str(DATA / f"exchange_{variant}.jsonl"), "--json", *options)
    assert done.returncode == 0, done.stderr
    records = [json.loads(line) for line in done.stdout.splitlines()]
    names = {r["name"] for r in records}
    assert "undecodable" not in names
    assert {"PING req", "PING SUCCESS", "JOINT_TRAJ_PT req", "JOINT_TRAJ_PT SUCCESS"} <= names
    stop = [r for r in records if r["fields"].get("sequence") == "-4(STOP)"]
    assert stop and stop[0]["dir"] == "c2s"


def test_a_closed_pipe_ends_quietly() -> None:
    proc = subprocess.Popen([*CLI, "sim"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.readline()
    proc.stdout.close()  # like `| head -1`
    assert proc.wait(20) == 0
    assert proc.stderr.read() == b""


def test_ctrl_c_exits_130_with_one_line() -> None:
    proc = subprocess.Popen([*CLI, "sim"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)  # fmt: skip
    assert proc.stdout is not None
    proc.stdout.readline()  # it runs
    _, err = ctrl_c(proc, 20)
    assert proc.returncode == 130
    assert err.splitlines() == ["robocli: interrupted"]


@pytest.mark.parametrize("args,code,text", [
    (["sim", "--ports", "x"], 2, "'x' is not one of 'both', 'motion', 'state'"),
    ([], 2, "give HOST or --file"),
    (["sim", "--output", "x.txt"], 2, ".jsonl"),
    (["127.0.0.1", "--motion-port", "1", "--state-port", "2"], 3, "connection refused"),
    (["sim", "--listen", "127.0.0.1:x"], 2, "--listen is [ADDR:]PORT"),
    (["sim", "--listen", "65534"], 2, "--listen is [ADDR:]PORT"),
])  # fmt: skip
def test_bad_input_one_line(args: list[str], code: int, text: str, tmp_path: Path) -> None:
    done = subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=30,
                          cwd=tmp_path)  # fmt: skip
    assert done.returncode == code
    assert len(done.stderr.splitlines()) == 1 and text in done.stderr
    assert "Traceback" not in done.stderr


def test_empty_capture_fails(tmp_path: Path) -> None:
    empty = tmp_path / "none.jsonl"
    empty.write_text('{"t": 0, "dir": "s2c", "hex": "00ff"}\n')
    done: Any = dump("--file", str(empty))
    assert done.returncode == 1 and "no Simple Message frame" in done.stderr


def test_an_invalid_header_is_shown_not_fatal(tmp_path: Path) -> None:
    capture = tmp_path / "bad.jsonl"
    bad = "0c000000000000000100000000000000"  # msg_type 0: the library refuses it
    good = sm.encode(sm.SimpleMessageType.PING, sm.CommType.TOPIC).hex()
    capture.write_text(f'{{"t": 0, "dir": "s2c", "hex": "{bad}{good}"}}\n')
    done = dump("--file", str(capture), "--json")
    assert done.returncode == 0, done.stderr
    first, second = (json.loads(line) for line in done.stdout.splitlines())
    assert first["name"] == "undecodable" and "msg_type is 0" in first["fields"]["error"]
    assert second["name"] == "PING"


def test_motion_only_dump_notices_a_dropped_link(make_sim: Any) -> None:
    """The motion port is quiet: the dump still sees the controller drop it, and says so."""
    sim, mp, sp = make_sim()
    proc = subprocess.Popen([*CLI, "127.0.0.1", "--ports", "motion", "--motion-port", str(mp),
                             "--state-port", str(sp)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)  # fmt: skip
    sim.wait_until(lambda s: s.motion_clients == 1, 10.0)  # the dump holds the port
    sim.close()
    out, err = proc.communicate(timeout=20)
    assert proc.returncode == 1, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert f":{mp}" in err and out == ""


def test_listen_records_another_programs_upload(make_sim: Any) -> None:
    """``--listen``: an uploader connects to the dump instead of the controller (which takes
    one client per port); its upload is shown both ways and runs; the port stays single."""
    from robocli.devices.arm import Arm
    from robocli.errors import DeviceError
    from robocli.kinematics import load_model
    from robocli.kinematics.trajectory import circle

    sim, mp, sp = make_sim()
    proc = subprocess.Popen([*CLI, "127.0.0.1", "--motion-port", str(mp), "--state-port",
                             str(sp), "--listen", "127.0.0.1:0", "--json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    assert proc.stderr is not None
    said = proc.stderr.readline()
    pm, ps = (int(p) for p in re.findall(r"127\.0\.0\.1:(\d+) ->", said))
    assert f"-> 127.0.0.1:{mp}" in said and f"-> 127.0.0.1:{sp}" in said
    with Arm.connect("127.0.0.1", pm, ps) as arm:
        sent = arm.download(circle(load_model("irb120"), 5, duration=1.0), first_duration=0.5)
        arm.wait_until_idle(10.0)
        assert sim.snapshot().motion_clients == 1  # the uploader's, through the dump
        with pytest.raises(DeviceError):  # the controller's refusal, relayed
            Arm.connect("127.0.0.1", pm, ps, motion=False, timeout=5.0)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=20)
    assert proc.returncode == 130 and err.splitlines() == ["robocli: interrupted"], err
    records = [json.loads(line) for line in out.splitlines()]
    requests = [r for r in records if (r["port"], r["dir"]) == ("motion", "c2s")]
    replies = [r for r in records if r["name"] == "JOINT_TRAJ_PT SUCCESS"]
    assert len(requests) == len(replies) == sent
    assert requests[0]["fields"]["sequence"] == "-1(start)"
    assert requests[-1]["fields"]["sequence"] == "-3(end)"
    assert {r["name"] for r in records if r["port"] == "state"} >= {"JOINT_POSITION", "STATUS"}


def test_listen_says_when_the_controller_is_unreachable() -> None:
    """The controller is not probed (that would take its one client slot): the first client
    that cannot be relayed ends the dump with exit 3 and one line."""
    import socket

    proc = subprocess.Popen([*CLI, "127.0.0.1", "--motion-port", "1", "--ports", "motion",
                             "--listen", "0"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)  # fmt: skip
    assert proc.stderr is not None
    (port,) = re.findall(r"127\.0\.0\.1:(\d+) ->", proc.stderr.readline())
    with socket.create_connection(("127.0.0.1", int(port)), timeout=5.0) as client:
        client.settimeout(5.0)
        assert client.recv(16) == b""  # closed: nothing to relay to
    _, err = proc.communicate(timeout=20)
    assert proc.returncode == 3 and len(err.splitlines()) == 1
    assert "no controller at 127.0.0.1:1" in err
