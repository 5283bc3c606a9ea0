"""The hub commands as a user runs them: real processes against the built-in hub."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from robocli import Hub
from robocli.hub_server import HubServer
from tests.waiting import wait_for


@pytest.fixture(scope="module")
def server() -> Iterator[HubServer]:
    with HubServer(bind="127.0.0.1", port=0, sim=True) as srv:
        yield srv


def cli(*args: str, env: dict[str, str] | None = None) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "robocli", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        text=True,
        env={**os.environ, **(env or {})},
    )


def finish(proc: subprocess.Popen[str], timeout: float = 60) -> tuple[int, str, str]:
    out, err = proc.communicate(timeout=timeout)
    return proc.returncode, out, err


def subscribed(server: HubServer, sensor: str, rate: str, *args: str) -> str:
    """The output of ``robocli subscribe SENSOR --rate RATE ARGS`` from ``server``, which
    exited 0."""
    code, out, err = finish(cli("subscribe", sensor, "--rate", rate, "--hub",
                                f"127.0.0.1:{server.port}", *args))  # fmt: skip
    assert code == 0, err
    return out


def test_two_concurrent_csv_subscribers_get_about_100_rows_per_second(server: HubServer) -> None:
    hub = f"127.0.0.1:{server.port}"
    args = ("subscribe", "adc", "--rate", "100", "--format", "csv", "--duration", "2")
    started = time.monotonic()
    procs = [cli(*args, "--hub", hub), cli(*args, env={"ROBOCLI_HUB": hub})]
    for proc in procs:
        code, out, err = finish(proc)
        ran = time.monotonic() - started
        assert code == 0, err
        lines = out.splitlines()
        assert lines[0] == "t,ch0,ch1,ch2,ch3,ch4,ch5,ch6,ch7"
        rows = np.array([[float(x) for x in line.split(",")] for line in lines[1:]])
        assert rows.shape[1] == 9
        # 2 s at 100 Hz (plus what the hub buffered before the first pull), at most what
        # the hub acquired while the process ran (longer on a loaded machine)
        assert 120 <= len(rows) <= 100 * ran + 20, (len(rows), ran)
        t = rows[:, 0]
        assert np.all(np.diff(t) > 0)
        np.testing.assert_allclose(np.median(np.diff(t)), 0.01, rtol=0.05)
        assert abs(t[-1] - time.time()) < 10


def test_count_jsonl_channel_mask_compressed(server: HubServer) -> None:
    out = subscribed(server, "adc", "200", "--count", "25", "--json", "--channels", "0x5",
                     "--compress")  # fmt: skip
    rows = [json.loads(line) for line in out.splitlines()]
    assert len(rows) == 25 and set(rows[0]) == {"t", "ch0", "ch2"}
    assert all(a["t"] < b["t"] for a, b in zip(rows, rows[1:], strict=False))


def test_plain_sensor_names_and_jsonl_at_the_wires_precision(server: HubServer) -> None:
    """`laser` is the hokuyo, `sysinfo` the computer; JSON values carry float32's digits
    (no 0.0018077874556183815 for a float32 0.0018077875)."""
    hub = f"127.0.0.1:{server.port}"
    code, out, err = finish(cli("subscribe", "imu", "--rate", "50", "--hub", hub,
                                "--count", "5", "--json"))  # fmt: skip
    assert code == 0, err
    for row in map(json.loads, out.splitlines()):
        for key, value in row.items():
            digits = repr(value).lstrip("-").replace(".", "").split("e")[0].strip("0")
            assert len(digits) <= (16 if key == "t" else 7), (key, value)
    code, out, err = finish(cli("subscribe", "laser", "--rate", "10", "--hub", hub,
                                "--count", "1", "--format", "csv"))  # fmt: skip
    assert code == 0 and len(out.splitlines()) == 2, err


def test_unknown_sensor_is_a_usage_error_naming_the_known_ones(server: HubServer) -> None:
    code, _, err = finish(cli("subscribe", "sonar", "--rate", "5",
                              "--hub", f"127.0.0.1:{server.port}"))  # fmt: skip
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "'sonar'" in err and "laser" in err and "Traceback" not in err


def test_table_without_a_terminal(server: HubServer) -> None:
    out = subscribed(server, "imu", "50", "--count", "5", "--format", "table")
    lines = out.splitlines()
    assert lines[0].split() == ["t", "ax", "ay", "az", "gx", "gy", "gz", "mx", "my", "mz"]
    assert len(lines) == 6 and len(lines[1].split()) == 10


def test_no_hub_exits_3_with_a_hint() -> None:
    code, out, err = finish(cli("subscribe", "adc", "--rate", "100", "--hub", "127.0.0.1:1"))
    assert code == 3 and out == ""
    assert err.count("\n") == 1 and "robocli serve --sim" in err


@pytest.mark.parametrize("args", [
    ("dump", "hub", "127.0.0.1:1", "--listen", "127.0.0.1:0"),
    ("bench", "rtt", "--target", "hub", "127.0.0.1:1"),
    ("bench", "throughput", "127.0.0.1:1"),
    ("connect", "hub", "127.0.0.1:1", "--once"),
])  # fmt: skip
def test_every_hub_command_says_how_to_start_a_hub(args: tuple[str, ...]) -> None:
    code, out, err = finish(cli(*args))
    assert code == 3 and err.count("\n") == 1, err
    assert "no hub at 127.0.0.1:1" in err and "robocli serve --sim" in err, err
    assert "sim pioneer" not in err and "robot" not in err, err


def test_usage_errors_exit_2(server: HubServer) -> None:
    hub = f"127.0.0.1:{server.port}"
    for args in (
        ("subscribe", "adc", "--rate", "100", "--hub", hub, "--count", "3", "--duration", "1"),
        ("subscribe", "adc", "--rate", "100", "--hub", hub, "--format", "xml"),
        ("subscribe", "adc", "--rate", "100", "--hub", hub, "--channels", "0x100"),
    ):
        code, _, err = finish(cli(*args))
        assert code == 2 and err.count("\n") == 1, err


def test_ctrl_c_exits_130_with_one_line(server: HubServer) -> None:
    proc = cli("subscribe", "adc", "--rate", "100", "--hub", f"127.0.0.1:{server.port}")
    assert proc.stdout is not None
    assert proc.stdout.readline().startswith("t,")  # streaming (csv: stdout is a pipe)
    proc.send_signal(signal.SIGINT)
    code, _, err = finish(proc)
    assert code == 130 and err.strip() == "robocli: interrupted"


def test_connect_hub_once_json(server: HubServer) -> None:
    with Hub.connect("127.0.0.1", server.port) as other:
        other.subscribe("imu", 100)
        code, out, err = finish(cli("connect", "hub", f"127.0.0.1:{server.port}", "--once",
                                    "--json", "--window", "0.3"))  # fmt: skip
    assert code == 0, err
    info = json.loads(out)
    assert info["protocol_version"] == 3 and info["client_id"] >= 1
    imu = info["sensors"]["imu"]
    assert imu["active"] and 50 <= imu["rate_hz"] <= 200
    assert info["sensors"]["stereo"]["active"] is False  # robocli's names, not the wire's
    assert not {"camera_stereo", "computer", "hokuyo", "kinect"} & set(info["sensors"])
    assert "kinect_ir" not in info["sensors"]  # 0x28: no pull, no hub serves it
    assert info["rtt_ms"] is not None and info["rtt_ms"] < 1000


def test_dump_hub_names_and_decodes_a_session(server: HubServer, tmp_path: Path) -> None:
    capture = tmp_path / "session.jsonl"
    proc = cli("dump", "hub", f"127.0.0.1:{server.port}", "--listen", "127.0.0.1:0", "--json",
               "--count", "6", "--output", str(capture))  # fmt: skip
    assert proc.stderr is not None
    line = proc.stderr.readline()
    port = int(line.split(" connect to ", 1)[1].split(",", 1)[0].rsplit(":", 1)[1])
    with Hub.connect("127.0.0.1", port) as h:
        h.subscribe("adc", 100)
        ring = server.hub.channel("adc").ring
        assert ring is not None
        pushed = ring.pushed
        wait_for(lambda: ring.pushed > pushed, "a batch of ADC samples")  # one pull gets it
        assert len(h.read("adc"))  # the 6th message: the proxy stops after it
    code, out, err = finish(proc)
    assert code == 0, err
    msgs = [json.loads(x) for x in out.splitlines()]
    names = [(m["dir"], m["name"]) for m in msgs]
    assert names[:4] == [("c2s", "CONNECT"), ("s2c", "CONNECT_ACK"), ("c2s", "SUBSCRIBE"),
                         ("s2c", "SUBSCRIBE_ACK")]  # fmt: skip
    assert msgs[2]["params"]["freq_acquisition"] == 100
    assert ("c2s", "ADC") in names[4:] and ("s2c", "ADC") in names[4:]
    assert len(capture.read_text().splitlines()) >= 6


@pytest.mark.parametrize("json_out", [False, True])
def test_dump_hub_file_reads_back_what_the_live_dump_showed(
    server: HubServer, tmp_path: Path, json_out: bool
) -> None:
    """``dump hub -o`` wrote captures that nothing read back: ``dump hub --file`` shows the
    same messages, decoded the same, as the live dump did (JSON: the same Unix ``t``)."""
    capture = tmp_path / "hub.jsonl"
    fmt = ["--json"] if json_out else []
    proc = cli("dump", "hub", f"127.0.0.1:{server.port}", "--listen", "127.0.0.1:0", *fmt,
               "--hex", "--count", "10", "-o", str(capture))  # fmt: skip
    assert proc.stderr is not None
    line = proc.stderr.readline()
    port = int(line.split(" connect to ", 1)[1].split(",", 1)[0].rsplit(":", 1)[1])
    with Hub.connect("127.0.0.1", port) as h:
        h.subscribe("adc", 100)
        h.subscribe("imu", 50)
        ring = server.hub.channel("adc").ring
        assert ring is not None
        pushed = ring.pushed
        wait_for(lambda: ring.pushed > pushed, "a batch of ADC samples")
        h.read("adc")
        h.read("imu")  # the 10th message: the proxy stops after it
    code, live, err = finish(proc)
    assert code == 0, err
    code, replay, err = finish(cli("dump", "hub", "--file", str(capture), *fmt, "--hex"))
    assert code == 0 and err == "", err
    if not json_out:
        assert replay == live and len(live.splitlines()) == 20  # a text and a hex line each
        return
    a, b = ([json.loads(x) for x in out.splitlines()] for out in (live, replay))
    assert len(a) == len(b) == 10
    for x, y in zip(a, b, strict=True):
        assert abs(x.pop("t") - y.pop("t")) < 1e-5 and x == y
    assert [m["name"] for m in b][:2] == ["CONNECT", "CONNECT_ACK"]


def test_laser_rows_summarise_each_scan(server: HubServer) -> None:
    out = subscribed(server, "hokuyo", "40", "--count", "3", "--format", "csv")
    lines = out.splitlines()
    assert lines[0] == "t,beams,min,max,mean" and len(lines) == 4
    beams, low, high = (float(x) for x in lines[1].split(",")[1:4])
    assert beams == 1081 and 0 <= low <= high


def test_bench_commands_against_a_hub_process() -> None:
    code, out, err = finish(cli("bench", "rtt", "--target", "hub", "-n", "50", "--json"))
    assert code == 0, err
    (rtt,) = json.loads(out)
    assert rtt["n"] == 50 and 0 < rtt["median"] < 1e6
    code, out, err = finish(cli("bench", "throughput", "--clients", "2", "--duration", "1",
                                "--sensors", "imu,adc", "--json"))  # fmt: skip
    assert code == 0, err
    report = json.loads(out)
    assert report["clients"] == 2 and report["pulls_per_s"] > 0 and not report["errors"]
    assert report["workers"] == 1  # five clients to a process by default
    assert report["per_sensor"]["adc"]["samples"] > 0 and report["hub_peak_rss_mb"] > 0
    code, _, err = finish(cli("bench", "throughput", "--sensors", "lidar"))
    assert code == 2 and "lidar" in err


def test_live_table_on_a_terminal(server: HubServer) -> None:
    import pty
    import re
    import select

    master, slave = pty.openpty()
    proc = subprocess.Popen(
        [sys.executable, "-m", "robocli", "subscribe", "adc", "--rate", "50", "--hub",
         f"127.0.0.1:{server.port}", "--count", "20"],
        stdout=slave, stderr=slave, stdin=subprocess.DEVNULL,
    )  # fmt: skip
    os.close(slave)
    out = b""
    try:
        while select.select([master], [], [], 30)[0]:
            try:
                chunk = os.read(master, 65536)
            except OSError:  # the child closed its side
                break
            if not chunk:
                break
            out += chunk
    finally:
        os.close(master)
    assert proc.wait(30) == 0
    text = out.decode(errors="replace")
    assert re.search(r"20 samples, [\d.]+/s", text)
    assert re.search(r"\d\d:\d\d\.\d{3}( +-?\d+\.\d{3}){8}", text)  # time, then 8 channels


def test_a_reader_that_leaves_ends_subscribe_quietly(server: HubServer) -> None:
    line = (f"{sys.executable} -m robocli subscribe adc --rate 100 --hub 127.0.0.1:{server.port}"
            " | head -3; exit ${PIPESTATUS[0]}")  # fmt: skip
    proc = subprocess.run(["bash", "-c", line], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and proc.stderr == ""
    assert len(proc.stdout.splitlines()) == 3


def test_dump_listen_in_use_exits_1_and_a_bad_address_2_in_one_line(server: HubServer) -> None:
    hub = f"127.0.0.1:{server.port}"
    code, out, err = finish(cli("dump", "hub", hub, "--listen", hub))
    assert code == 1 and out == "" and err.count("\n") == 1, err
    assert f"port {server.port} is in use" in err
    for bad in ("garbage.invalid", "192.0.2.1:0"):
        code, out, err = finish(cli("dump", "hub", hub, "--listen", bad))
        assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err


def _children(pid: int) -> list[int]:
    """The pids of ``pid``'s child processes (Linux /proc)."""
    kids = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                kids.append(int(entry.name))
    return kids


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_ctrl_c_during_bench_throughput_exits_130_in_one_line() -> None:
    """Ctrl-C on a terminal reaches the whole process group, the client workers included:
    they stay quiet and the parent stops them."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "robocli", "bench", "throughput", "--clients", "2",
         "--duration", "30", "--sensors", "imu"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True,
        start_new_session=True,
    )  # fmt: skip
    try:
        wait_for(lambda: len(_children(proc.pid)) >= 2, "the hub and a worker", timeout=60)
        kids = _children(proc.pid)
        assert len(kids) >= 2, kids
        time.sleep(1.0)  # the workers' clients are running
        os.killpg(proc.pid, signal.SIGINT)
        code, out, err = finish(proc, 30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(10)
    assert code == 130 and err.strip() == "robocli: interrupted", err
    # the workers end with their parent: no worker left behind
    wait_for(lambda: not [k for k in kids if Path(f"/proc/{k}").exists()], "the workers' end")
    assert not [k for k in kids if Path(f"/proc/{k}").exists()]


def test_token_file_for_a_hub_that_has_one(tmp_path: Path) -> None:
    """``--token-file`` (or $ROBOCLI_HUB_TOKEN_FILE), read as ``serve --token-file`` reads
    it: the right token subscribes, a wrong or missing one exits 4 "unauthorized"."""
    right, wrong = tmp_path / "right", tmp_path / "wrong"
    right.write_text("s3cret\n")
    wrong.write_text("guess\n")
    with HubServer(bind="127.0.0.1", port=0, sim=True, token=b"s3cret") as srv:
        args = ("subscribe", "adc", "--rate", "50", "--hub", f"127.0.0.1:{srv.port}",
                "--count", "3", "--format", "csv")  # fmt: skip
        code, out, err = finish(cli(*args, "--token-file", str(right)))
        assert code == 0 and len(out.splitlines()) == 4, err
        code, out, err = finish(cli(*args, env={"ROBOCLI_HUB_TOKEN_FILE": str(right)}))
        assert code == 0 and len(out.splitlines()) == 4, err
        for extra in (("--token-file", str(wrong)), ()):
            code, out, err = finish(cli(*args, *extra))
            assert code == 4 and err.count("\n") == 1 and "unauthorized" in err, err
        code, out, err = finish(cli(*args, "--token-file", str(tmp_path / "none")))
        assert code == 2 and err.count("\n") == 1 and "cannot read" in err, err


def test_subscribe_says_how_many_samples_the_hub_dropped(server: HubServer) -> None:
    """1.2 s of a 1000 Hz ADC through a buffer of 10, pulled twice a second: most samples
    are lost, and the last line says how many. Each lost or printed sample was acquired
    while the subscriber ran (the hub's times), however slowly a loaded machine runs it."""
    started = time.monotonic()
    code, out, err = finish(cli("subscribe", "adc", "--rate", "1000", "--buffer", "10",
                                "--poll", "2", "--duration", "1.2", "--format", "csv",
                                "--hub", f"127.0.0.1:{server.port}"))  # fmt: skip
    ran = time.monotonic() - started
    assert code == 0, err
    rows = len(out.splitlines()) - 1
    last = err.strip().splitlines()[-1]
    assert "adc samples lost (gaps in their times)" in last and "--buffer" in last, err
    lost = int(last.split()[1])
    # pulled for 1.2 s from samples the hub batches every 0.5 s (--poll): at least 0.7 s
    assert 700 - 10 <= lost + rows <= 1000 * ran + 10, (err, rows, ran)


def test_subscribe_says_the_total_lost_at_the_end(server: HubServer) -> None:
    """The total lost is said at the end even when a "so far" line already gave it (the
    losses all came before the last reading): the last line was "lost so far".

    The hub loses samples when its 10-sample buffer overflows before the first pull; a hub
    starved by a loaded machine may sample so late that the first pull finds no overflow:
    that run has nothing to say, and the command is run again (at most 5 times)."""
    for _ in range(5):
        code, out, err = finish(cli("subscribe", "adc", "--rate", "1000", "--buffer", "10",
                                    "--poll", "2", "--count", "10", "--format", "csv",
                                    "--hub", f"127.0.0.1:{server.port}"))  # fmt: skip
        assert code == 0 and len(out.splitlines()) == 11, err  # one full reading
        if err.strip():
            break
    said = err.strip().splitlines()
    assert "so far" in said[0] and len(said) == 2, err
    assert said[-1].startswith(said[0].split(" so far")[0]) and "so far" not in said[-1], err


def test_poll_is_an_integer_in_hz_as_the_protocol_field_is(server: HubServer) -> None:
    code, out, err = finish(cli("subscribe", "--help"))
    assert code == 0, err
    poll = out[out.index("--poll") :].split("--channels")[0]
    assert "INTEGER" in poll and "Hz" in poll and "1<=x<=65535" in poll, poll
    code, _, err = finish(cli("subscribe", "adc", "--rate", "100", "--poll", "0.5",
                              "--hub", f"127.0.0.1:{server.port}"))  # fmt: skip
    assert code == 2 and err.count("\n") == 1 and "--poll" in err, err


def test_subscribe_names_the_sensors_and_refuses_kinect_ir_and_an_empty_mask() -> None:
    """One set of sensor names (issue 22): help says robocli's, the wire's stay on the wire."""
    code, out, err = finish(cli("subscribe", "--help"))
    assert code == 0, err
    for name in ("sysinfo", "laser", "stereo", "depth"):
        assert name in out, out
    for wire in ("computer", "hokuyo", "camera_stereo", "kinect"):
        assert wire not in out, out
    for args in (("kinect_ir", "--rate", "5"), ("adc", "--rate", "5", "--channels", "0")):
        code, out, err = finish(cli("subscribe", *args, "--hub", "127.0.0.1:1"))
        assert code == 2 and err.count("\n") == 1, err  # refused before connecting
    code, _, err = finish(cli("subscribe", "sonar", "--rate", "5", "--hub", "127.0.0.1:1"))
    assert "kinect_ir" not in err and "laser" in err and "hokuyo" not in err, err


def test_connect_hub_output_without_data_and_json_lines_when_repeating() -> None:
    with HubServer(bind="127.0.0.1", port=0, sim=True) as srv:
        hub = f"127.0.0.1:{srv.port}"
        code, out, err = finish(cli("connect", "hub", hub, "--once", "--window", "0.1"))
        assert code == 0, err
        assert "None" not in out, out  # nothing running: the rtt and offset of CONNECT
        assert re.search(r"rtt [\d.]+ ms  clock offset -?[\d.]+ ms", out), out
        with Hub.connect(hub) as other:
            other.subscribe("gps", 1)  # running, at times with no sample in a window
            _connect_hub_json_lines(hub)


def _connect_hub_json_lines(hub: str) -> None:
    proc = cli("connect", "hub", hub, "--json", "--window", "0.1")
    assert proc.stdout is not None
    lines = [proc.stdout.readline() for _ in range(2)]
    proc.send_signal(signal.SIGINT)
    code, _, err = finish(proc)
    assert code == 130, err
    for line in lines:  # JSON Lines: one compact object per line
        assert json.loads(line)["protocol_version"] == 3, lines


def _not_json(name: str) -> None:
    raise AssertionError(f"{name} is not JSON")


def test_jsonl_rows_are_strict_json_with_integers_as_ints(server: HubServer) -> None:
    hub = f"127.0.0.1:{server.port}"
    for sensor, key in (("camera", "height"), ("sysinfo", "mem_used"), ("laser", "beams")):
        code, out, err = finish(cli("subscribe", sensor, "--rate", "5", "--hub", hub,
                                    "--count", "1", "--json"))  # fmt: skip
        assert code == 0, err
        row = json.loads(out.splitlines()[0], parse_constant=_not_json)
        assert isinstance(row[key], int), row


def test_dump_output_it_cannot_write_is_a_usage_error(server: HubServer) -> None:
    hub = f"127.0.0.1:{server.port}"
    for path in ("/nonexistent/x.jsonl", "/tmp/capture.txt"):
        code, _, err = finish(cli("dump", "hub", hub, "--listen", "127.0.0.1:0", "-o", path))
        assert code == 2 and err.count("\n") == 1 and path in err, err
