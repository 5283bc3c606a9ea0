"""The text the commands print, as a notebook gets it from the library: dump's packet lines
(robocli.analysis.text), info's summary (robocli.views.recording), connect hub's survey
(robocli.views.hub), doctor's report (robocli.views.doctor) and the bench tables
(robocli.bench.text); read from real captures, recordings and simulators."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from robocli.analysis import read_packets
from robocli.analysis.packets import Packet, PacketLog
from robocli.analysis.text import (
    LINE_MAX,
    arm_line,
    ellipsis,
    hub_line,
    hub_record,
    laser_lines,
    pioneer_line,
    pioneer_record,
)
from robocli.bench.text import hub_rtt_lines, results_lines, throughput_lines, unit_of
from robocli.devices.hub.client import Hub
from robocli.devices.hub.tools import survey
from robocli.diagnostics import diagnose
from robocli.io.record import info
from robocli.views.doctor import doctor_lines
from robocli.views.hub import survey_lines
from robocli.views.recording import info_lines, size_text, when_text
from tests.io.recordings import record_pioneer_drive

ARCOS = Path(__file__).parents[1] / "data" / "arcos" / "a_simpleConnect.jsonl"


def test_pioneer_packets_as_lines_cut_unless_full_and_as_records() -> None:
    packets = list(read_packets(ARCOS, "arcos"))
    sip = next(p for p in packets if p.name.startswith("SIP") or "sonar" in p.fields)
    short, full = pioneer_line(sip), pioneer_line(sip, full=True)
    assert len(short) <= LINE_MAX and len(full) >= len(short)
    assert sip.name in short and short.split()[1] in ("->", "<-")
    log = PacketLog(lambda d, f, t: sip, lambda p: None)
    log.start(1_700_000_000.0)
    record = json.loads(json.dumps(pioneer_record(log, sip)))
    assert record["dir"] in ("c2s", "s2c") and record["name"] == sip.name
    assert record["t"] is None or record["t"] > 1e9
    assert ellipsis("ascii") == "..." and ellipsis("utf-8") == "\u2026"


def test_arm_hub_and_laser_packets_as_lines() -> None:
    arm = Packet(1.5, "rx", "JOINT_FEEDBACK", {"sequence": 3, "joints": [0.1] * 6}, b"\x00",
                 port="state")  # fmt: skip
    line = arm_line(arm)
    assert line.startswith("    1.500 state  <- JOINT_FEEDBACK") and "seq=3" in line
    hub = Packet(None, "tx", "GET_DATA", {"type": 2}, b"\x01\x02")
    assert hub_line(hub) == "         - -> GET_DATA       type=2"
    log = PacketLog(lambda d, f, t: hub, lambda p: None)
    assert json.loads(hub_record(log, hub, hex_out=True))["hex"] == "0102"
    scan = Packet(2.0, "tx", "GD", {}, b"GD\n", lines=(), port=None)
    assert laser_lines(log, scan, [], json_out=False) == []


def test_info_lines_summarise_a_real_recording(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    record_pioneer_drive(path, "sim://")
    lines = info_lines(info(path))
    assert lines[0] == f"File:        {path}" and lines[1].startswith("Size:")
    assert any(line.startswith("Messages:") for line in lines)
    assert any("/pioneer" in line for line in lines[-5:])
    assert size_text(512) == "512 B" and size_text(1536) == "1.5 KiB"
    assert when_text(1_700_000_000_000_000_000).endswith("(1700000000.000000)")


def test_survey_lines_of_a_simulated_hub() -> None:
    with Hub.connect("sim://") as hub:
        lines = survey_lines(survey(hub, 0.2, ("imu", "adc")))
    assert lines[0].startswith("hub ") and "ros4mat v" in lines[0]
    assert [line.split()[0] for line in lines[1:]] == ["imu", "adc"]


def test_doctor_lines_of_this_machine() -> None:
    lines = doctor_lines(diagnose(pioneer="127.0.0.1:9", arm="127.0.0.1", hub="127.0.0.1:9",
                                  timeout=0.2))  # fmt: skip
    assert lines[0].startswith("robocli ") and lines[2].startswith("C core")
    assert any(line.startswith("pioneer") and "127.0.0.1:9" in line for line in lines)


def test_bench_tables_in_their_units() -> None:
    row = {"name": "client rtt", "n": 10, "mean": 120.0, "median": 110.0, "std": 5.0,
           "min": 100.0, "max": 200.0, "p90": 150.0, "p99": 190.0, "x_floor_median": 2.0,
           "x_floor_p99": 3.0}  # fmt: skip
    lines = results_lines([row], {"period": np.full(20, 0.1)}, "a note")
    assert lines[1].split()[:3] == ["client", "rtt", "us"] and "2.0 x floor" in lines[2]
    assert lines[3] == "a note" and lines[4] == "histogram: period (ms)"
    assert unit_of(100_000) == (1e-3, "ms")
    hub = hub_rtt_lines({**row, "where": "loopback"})
    assert len(hub) == 3 and hub[2] == "  loopback"
    report = {"clients": 2, "workers": 1, "sensors": ["imu"], "pull_hz": 20.0, "seconds": 1.0,
              "not_served": [], "pulls_per_s": 40.0, "samples_per_s": 400.0, "bytes_per_s": 1e6,
              "lost_samples": 0, "per_sensor": {"imu": {"pulls": 40, "samples": 400,
              "bytes": 1e6, "lost": 0}}, "errors": [], "targets_met": True}  # fmt: skip
    text = throughput_lines(report)
    assert text[0].startswith("2 clients in 1 processes") and text[-1].endswith("met")


def test_snapshot_lines_of_a_simulated_pioneer() -> None:
    from robocli import Pioneer
    from robocli.views.pioneer import snapshot_lines

    with Pioneer.connect("sim://") as robot:
        robot.wait_for_sip()
        lines = snapshot_lines(robot)
    assert lines[0].endswith(robot.transport.url) and lines[1].startswith("pose      x ")
    assert lines[3].startswith("battery") and lines[4].startswith("sonar (m)")


def test_sample_rows_as_csv_table_and_json_lines() -> None:
    from robocli.views.hub import header_text, rows_text

    cols, rows = ("t", "x"), np.array([[1700000000.5, 0.25]])
    assert header_text("csv", cols) == "t,x\n" and header_text("jsonl", cols) == ""
    assert rows_text("csv", cols, rows) == "1700000000.500000,0.25\n"
    assert rows_text("table", cols, rows).split() == ["1700000000.500000", "0.25"]
    assert json.loads(rows_text("jsonl", cols, rows))["x"] == 0.25


def test_comparison_text_of_a_run_with_itself(tmp_path: Path) -> None:
    from robocli.io.compare import compare_files
    from robocli.kinematics import load_model
    from robocli.kinematics.files import write_trajectory
    from robocli.kinematics.trajectory import circle
    from robocli.views.compare import COLUMNS, joint_rows, mm_text, notes, rad_text, title

    model = load_model("irb120")
    log = tmp_path / "sim.json"
    write_trajectory(model, circle(model, 50, 0.05, None, "xy", None, None, 2.0), "circle", log,
                     None)  # fmt: skip
    result = compare_files(log, log, "irb120")
    rows = joint_rows(result)
    assert len(rows) == 6 and len(rows[0]) == len(COLUMNS) and rows[0][0] == "1"
    assert title(result).startswith("sim vs real: ") and notes(result)[0].startswith("time shift")
    assert rad_text(1e-7) == "1.00e-07" and mm_text(None) == "-" and mm_text(0.5) == "0.500"


def test_recording_progress_and_what_it_wrote(tmp_path: Path) -> None:
    from robocli.io.record import Recorder
    from robocli.io.record.session import Progress
    from robocli.views.recording import progress_text, recorded_text

    assert progress_text(Progress(10, 2048, 2.0)) == "10 messages, 2.0 KiB, 5 msg/s, 2 s"
    with Recorder(tmp_path / "empty.mcap") as rec:
        pass
    assert recorded_text(rec, 1.25).startswith("recorded 0 messages in 1.2 s to ")


def test_placed_scans_and_serial_ports_for_a_notebook() -> None:
    from robocli.transports import list_serial_ports
    from robocli.views.laser import LASER_RESOLUTION

    assert all(set(p) == {"device", "description", "hwid"} for p in list_serial_ports())
    assert LASER_RESOLUTION["points_robot"] == 4
