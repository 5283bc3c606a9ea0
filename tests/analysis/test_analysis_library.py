"""robocli.analysis, robocli.io.record.session and robocli.hub_server.service called as a notebook
calls them: captures read as packets, live sessions of the simulators ordered, a recording
wired and run, a hub served; nothing printed (issues 22 and 23)."""

from __future__ import annotations

import contextlib
import threading
from pathlib import Path
from typing import Any

import pytest

from robocli.analysis import PacketLog, read_packets
from robocli.analysis.packets import Packet
from robocli.analysis.sessions import arm_check, arm_clients, decoder, hub_proxy, replay_capture
from robocli.devices.hub.client import Hub
from robocli.errors import InvalidArgument, RobocliError
from robocli.hub_server import HubServer
from robocli.io.record import Recorder, info
from robocli.io.record.session import HUB_DEFAULTS, RecordingSession, hub_sensors
from robocli.sim.abb.server import AbbSim
from tests.waiting import wait_for

DATA = Path(__file__).resolve().parents[1] / "data"


def test_a_capture_reads_as_named_packets_in_time_order(
    capsys: pytest.CaptureFixture[str],
) -> None:
    packets = list(read_packets(DATA / "arcos" / "a_simpleConnect.jsonl", "arcos"))
    names = [p.name for p in packets]
    assert names[:3] == ["SYNC0", "SYNC0-reply", "SYNC1"]
    assert "SYNC2-reply" in names and "SIP" in " ".join(names)
    assert {p.direction for p in packets} == {"tx", "rx"}
    times = [p.t for p in packets if p.t is not None]
    assert times == sorted(times) and times
    reply = packets[names.index("SYNC2-reply")]
    assert set(reply.fields) == {"name", "type", "subtype"} and reply.wire_dir == "s2c"
    assert capsys.readouterr() == ("", "")  # the library never prints


def test_simple_message_and_recording_captures_decode() -> None:
    arm = list(read_packets(DATA / "simple_message" / "exchange_le.jsonl", "sm-le"))
    assert arm and all(p.name != "undecodable" for p in arm)
    recording = list(read_packets(DATA / "recordings" / "pioneer-robocli-raw.mcap", "arcos"))
    assert any(p.name == "SYNC2-reply" for p in recording)


def test_a_file_without_a_frame_is_said_so(tmp_path: Path) -> None:
    empty = tmp_path / "empty.jsonl"
    empty.write_text("")
    log = PacketLog(decoder("ros4mat"), lambda p: None)
    with pytest.raises(RobocliError, match="no ros4mat message"):
        replay_capture(log, empty, "ros4mat")


def test_a_scip_capture_of_a_live_laser_session_reads_back(tmp_path: Path) -> None:
    from robocli.devices.laser import Laser
    from robocli.io.capture import CaptureWriter
    from robocli.sim.hokuyo import HokuyoSim

    path = tmp_path / "laser.jsonl"
    writer = CaptureWriter(path)
    live: list[Packet] = []
    log = PacketLog(decoder("scip2"), live.append, writer=writer)
    with HokuyoSim("utm-30lx") as sim:
        with Laser.connect(sim.serve_tcp("127.0.0.1", 0), listeners=[log.direct]) as laser:
            laser.scan()
    writer.close()
    log.check()
    again = list(read_packets(path, "scip2"))
    assert [p.lines for p in again] == [p.lines for p in live]
    assert any(line.what.startswith("status") for p in again for line in p.lines)


def test_two_links_of_an_arm_come_out_in_time_order() -> None:
    got: list[Packet] = []
    log = PacketLog(decoder("sm-le", n_joints=6), got.append, count=12)
    with AbbSim("irb120", feedback=True) as sim, contextlib.ExitStack() as stack:
        motion, state = sim.serve_tcp("127.0.0.1", 0, 0)
        address = ("127.0.0.1", int(motion.rsplit(":", 1)[1]), int(state.rsplit(":", 1)[1]))
        log.start_now()
        arms = arm_clients(stack, log, address, "both", timeout=5.0)
        log.follow(arm_check(arms, [], "both", 5.0))
    log.drain()
    assert len(got) == 12 and log.epoch is not None
    assert [p.t for p in got] == sorted(p.t for p in got if p.t is not None)
    assert {p.port for p in got} <= {"motion", "state"}
    assert "JOINT_POSITION" in {p.name for p in got}


def test_a_hub_session_through_the_proxy_is_named() -> None:
    got: list[Packet] = []
    log = PacketLog(decoder("ros4mat"), got.append)
    with HubServer("127.0.0.1", 0, sim=True) as server:  # started
        with hub_proxy(log, ("127.0.0.1", server.port), "127.0.0.1", 0).start() as proxy:
            with Hub.connect("127.0.0.1", proxy.port) as hub:
                hub.subscribe("imu", rate=50)
                wait_for(lambda: len(got) >= 4, "4 messages through the proxy")
    log.check()
    assert got[0].direction == "tx" and got[1].direction == "rx"
    assert all(p.name != "undecodable" for p in got)


def test_hub_sensors_parse_and_name_the_cli_choices() -> None:
    from robocli.commands.record import HUB_SENSORS

    assert hub_sensors("imu, adc:500") == [("imu", {"rate": 200}), ("adc", {"rate": 500})]
    assert HUB_SENSORS == tuple(HUB_DEFAULTS)
    for bad in ("kinect", "imu:0", " , "):
        with pytest.raises(InvalidArgument):
            hub_sensors(bad)


def test_a_recording_session_records_a_simulated_pioneer(tmp_path: Path) -> None:
    out = tmp_path / "run.mcap"
    rec = Recorder(out, deferred=True)
    ticks = threading.Event()
    with contextlib.ExitStack() as stack:
        run = RecordingSession(rec, stack)
        name = run.add_pioneer("sim://")
        rec.begin()
        run.run(count=40, on_tick=ticks.set)
    rec.close()
    assert ticks.is_set() and name in run.devices
    progress = run.progress()
    assert progress.messages >= 40 and progress.size > 0 and progress.rate > 0
    assert info(out).messages >= 40


def test_a_recording_session_raises_when_a_link_is_lost(tmp_path: Path) -> None:
    rec = Recorder(tmp_path / "lost.mcap", deferred=True)
    with contextlib.ExitStack() as stack:
        run = RecordingSession(rec, stack)
        run.add_pioneer("sim://")
        rec.begin()
        robot: Any = run.devices[next(iter(run.devices))]
        robot.close()
        with pytest.raises(RobocliError):
            run.run(duration=30)
    rec.close()


def test_a_hub_service_serves_and_says_what() -> None:
    from robocli.hub_server.service import HubService

    with HubService("127.0.0.1", 0, sim=True) as service:
        service.start_tcp()
        served = service.served()
        assert served.startswith("hub serving ") and service.server.url in served
        with Hub.connect("127.0.0.1", service.server.port) as hub:
            hub.subscribe("imu", rate=50)
            wait_for(lambda: any(line.startswith("client ") for line in service.status_lines()),
                     "the client in the status")
            assert any(line.startswith("sensor imu") for line in service.status_lines())
        assert set(service.published("imu,adc")) == {"imu", "adc"}
        with pytest.raises(InvalidArgument):
            service.published("imu=nope")
