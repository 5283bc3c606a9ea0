"""``serve --replay``: a hub serving a recording gives a ros4mat client the recorded samples
with their recorded spacing (on the hub's sample times, never the wall clock)."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from robocli.devices.hub.client import Hub
from robocli.errors import RobocliError
from robocli.hub_server import HubServer
from robocli.hub_server.sources.replay import read_hub_recording, replay_sources
from robocli.io.record import Recorder
from tests.paths import DATA
from tests.waiting import wait_for

SENSORS = {"imu": {"rate": 200}, "adc": {"rate": 500, "channels": 0xFF},
           "camera": {"rate": 10, "resolution": "160x120"}, "laser": {"rate": 10},
           "gps": {"rate": 5}}  # fmt: skip
COUNT = {"imu": 60, "adc": 150, "camera": 4, "laser": 4, "gps": 3}


class Pulled:
    """Every sample of one sensor read so far: data (samples on the last axis), hub times."""

    def __init__(self) -> None:
        self.data: list[Any] = []
        self.hub_t: list[Any] = []

    def add(self, reading: Any) -> None:
        if len(reading):
            self.data.append(np.array(reading.data))
            self.hub_t.append(np.array(reading.hub_t))

    def __len__(self) -> int:
        return sum(len(t) for t in self.hub_t)

    def arrays(self) -> tuple[Any, Any]:
        return np.concatenate(self.data, axis=-1), np.concatenate(self.hub_t)


def pull_all(hub: Hub, pulled: dict[str, Pulled], names: Any) -> None:
    for name in names:
        pulled.setdefault(name, Pulled()).add(hub.read(name))


@pytest.fixture
def recording(hub_server: HubServer, tmp_path: Path) -> tuple[Path, dict[str, Pulled]]:
    """A short recording of the simulated hub, and what its client read meanwhile."""
    path = tmp_path / "hub.mcap"
    pulled: dict[str, Pulled] = {}
    with Recorder(path) as rec, Hub.connect(f"127.0.0.1:{hub_server.port}") as hub:
        rec.add(hub, sensors=tuple(SENSORS))
        for name, params in SENSORS.items():
            hub.subscribe(name, **params)

        def enough() -> bool:
            pull_all(hub, pulled, SENSORS)
            return all(len(pulled[n]) >= COUNT[n] for n in SENSORS)

        wait_for(enough, what="samples of every sensor")
    return path, pulled


@pytest.fixture
def replay_hub(recording: tuple[Path, dict[str, Pulled]]) -> Iterator[HubServer]:
    with HubServer(port=0, sim=False, sources=replay_sources(recording[0])) as srv:
        yield srv


def test_recording_reads_back_as_the_client_read_it(
        recording: tuple[Path, dict[str, Pulled]]) -> None:  # fmt: skip
    path, pulled = recording
    sensors = read_hub_recording(path)
    assert set(SENSORS) <= set(sensors)
    for name in SENSORS:
        _, hub_t = pulled[name].arrays()
        assert sensors[name].t.tolist() == hub_t.tolist()


def _replayed(srv: HubServer, pulled: dict[str, Pulled], **subscribe: Any
              ) -> dict[str, Pulled]:  # fmt: skip
    """Subscribe to every recorded sensor of the replay hub and read until each has served
    its last recorded sample (matched by value)."""
    got: dict[str, Pulled] = {}
    with Hub.connect(f"127.0.0.1:{srv.port}") as hub:
        for name, params in SENSORS.items():
            hub.subscribe(name, **{**params, **subscribe})

        def ended() -> bool:
            pull_all(hub, got, SENSORS)
            done = True
            for name in SENSORS:
                last = pulled[name].arrays()[0][..., -1]
                have = got[name]
                done = done and bool(len(have)) and np.array_equal(have.data[-1][..., -1], last)
            return done

        wait_for(ended, what="the last recorded sample of every sensor")
    return got


def test_serve_replay_gives_recorded_values_and_spacing(
        recording: tuple[Path, dict[str, Pulled]], replay_hub: HubServer) -> None:  # fmt: skip
    _, pulled = recording
    got = _replayed(replay_hub, pulled)
    for name in SENSORS:
        data, hub_t = got[name].arrays()
        rec_data, rec_t = pulled[name].arrays()
        n = hub_t.shape[0]
        assert n >= 1
        # a sensor subscribed after the first one joins the timeline where it is: it gets
        # the recording's tail, each sample once, every value as recorded
        assert np.array_equal(data, rec_data[..., -n:]), name
        assert np.diff(hub_t) == pytest.approx(np.diff(rec_t[-n:]), abs=2e-6), name
    # the sensors keep their recorded offsets from each other on the one timeline
    first = {name: got[name].arrays()[1][-1] - pulled[name].arrays()[1][-1] for name in SENSORS}
    assert max(first.values()) - min(first.values()) == pytest.approx(0, abs=2e-6)


def test_speed_and_loop(recording: tuple[Path, dict[str, Pulled]]) -> None:
    path, pulled = recording
    rec_data, rec_t = pulled["imu"].arrays()
    sources = replay_sources(path, speed=4.0, loop=True)
    got = Pulled()
    with HubServer(port=0, sim=False, sources=sources) as srv, \
            Hub.connect(f"127.0.0.1:{srv.port}") as hub:  # fmt: skip
        hub.subscribe("imu", rate=200)
        wait_for(lambda: got.add(hub.read("imu")) or len(got) > len(rec_t) + 5,
                 what="a second lap")  # fmt: skip
    data, hub_t = got.arrays()
    n = len(rec_t)
    assert np.array_equal(data[..., :n], rec_data)  # the only sensor: the whole recording
    assert np.array_equal(data[..., n : n + 5], rec_data[..., :5])  # and again
    assert np.diff(hub_t[:n]) == pytest.approx(np.diff(rec_t) / 4.0, abs=2e-6)
    period = sources["imu"].timeline.period
    assert hub_t[n] - hub_t[0] == pytest.approx(period / 4.0, abs=2e-6)
    assert period > rec_t[-1] - rec_t[0]


def test_replay_of_a_recording_without_hub(pioneer_url: str, tmp_path: Path) -> None:
    from robocli.devices.pioneer import Pioneer

    path = tmp_path / "pioneer.mcap"
    with Recorder(path) as rec, Pioneer.connect(pioneer_url) as robot:
        rec.add(robot)
        wait_for(lambda: rec.stats.messages > 3, what="a few SIPs recorded")
    with pytest.raises(RobocliError, match="no raw ros4mat channel"):
        replay_sources(path)


def test_serve_replay_cli(recording: tuple[Path, dict[str, Pulled]]) -> None:
    path, pulled = recording
    proc = subprocess.Popen(
        [sys.executable, "-m", "robocli", "serve", "--replay", str(path), "--port", "0",
         "--speed", "2"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert "replaying" in line and "imu" in line, line
        url = line.rsplit(" ", 1)[1].strip()
        got = Pulled()
        with Hub.connect(url) as hub:
            hub.subscribe("imu", rate=200)
            wait_for(lambda: got.add(hub.read("imu")) or len(got) >= 10, what="replayed imu")
        data, hub_t = got.arrays()
        rec_data, rec_t = pulled["imu"].arrays()
        assert np.array_equal(data[..., :10], rec_data[..., :10])
        assert np.diff(hub_t[:10]) == pytest.approx(np.diff(rec_t[:10]) / 2, abs=2e-6)
    finally:
        proc.terminate()
        proc.wait(timeout=30)
        assert proc.stdout is not None and proc.stderr is not None
        proc.stdout.close()
        proc.stderr.close()


@pytest.mark.parametrize("args", [["--speed", "0"], ["--loop"], ["--speed", "2"]])
def test_replay_options_need_each_other(args: list[str], tmp_path: Path) -> None:
    if "--speed" in args and args[1] == "0":
        args = ["--replay", str(tmp_path / "x.mcap"), *args]
    result = subprocess.run([sys.executable, "-m", "robocli", "serve", *args],
                            capture_output=True, text=True, timeout=60)  # fmt: skip
    assert result.returncode == 2, result.stderr


def test_depth_stereo_and_jpeg_frames_replay_as_recorded(hub_server: HubServer,
                                                          tmp_path: Path) -> None:  # fmt: skip
    path = tmp_path / "images.mcap"
    subs = {"depth": {"rate": 5, "resolution": "64x48"},
            "stereo": {"rate": 5, "resolution": "64x48"},
            "battery": {"rate": 5}, "sysinfo": {"rate": 5}}  # fmt: skip
    try:
        import PIL  # noqa: F401

        subs["camera"] = {"rate": 5, "resolution": "64x48", "quality": 80}
    except ImportError:
        pass
    with Recorder(path) as rec, Hub.connect(f"127.0.0.1:{hub_server.port}") as hub:
        rec.add(hub)
        recorded = _three_readings_each(hub, subs, "frames of every image sensor")
    with HubServer(port=0, sim=False, sources=replay_sources(path, speed=4.0, loop=True)) as srv, \
            Hub.connect(f"127.0.0.1:{srv.port}") as hub:  # fmt: skip
        got = _three_readings_each(hub, subs, "replayed frames of every sensor")
    for name in subs:
        frames = {f for r in recorded[name] for f in _frames(r)}
        replayed_frames = [f for r in got[name] for f in _frames(r)]
        # every frame served is one of the recording's, each field byte for byte
        assert replayed_frames and all(f in frames for f in replayed_frames), name


def _three_readings_each(hub: Hub, subs: dict[str, dict[str, Any]],
                         what: str) -> dict[str, list[Any]]:  # fmt: skip
    """Subscribe ``hub`` to ``subs`` and read until each sensor has given 3 samples: the
    readings, by sensor."""
    for name, params in subs.items():
        hub.subscribe(name, **params)
    got: dict[str, list[Any]] = {}

    def enough() -> bool:
        for name in subs:
            reading = hub.read(name)
            if len(reading):
                got.setdefault(name, []).append(reading)
        return all(sum(len(r) for r in got.get(n, [])) >= 3 for n in subs)

    wait_for(enough, what=what)
    return got


def _frames(reading: Any) -> list[bytes]:
    """Each sample of a reading as the bytes of its data and fields (times left out)."""
    arrays = [reading.data, *(v for k, v in sorted(reading.fields.items())
                              if not k.endswith("_t"))]  # fmt: skip
    return [b"".join(np.ascontiguousarray(np.asarray(a)[..., j]).tobytes() for a in arrays)
            for j in range(len(reading))]  # fmt: skip


def test_replay_memory_is_bounded(recording: tuple[Path, dict[str, Pulled]]) -> None:
    with pytest.raises(RobocliError, match="MiB of samples"):
        replay_sources(recording[0], max_bytes=4096)


def test_a_stalled_replay_skips_what_it_missed_beyond_the_catch_up() -> None:
    from robocli.hub_server.sources.replay import (
        MAX_CATCH_UP_S,
        RecordedSensor,
        ReplaySource,
        ReplayTimeline,
    )
    from robocli.protocols.ros4mat import record_dtype

    n = 2000  # 20 s at 100 Hz
    records = np.zeros(n, dtype=record_dtype("imu"))
    records["t"] = 1000.0 + np.arange(n) / 100.0
    records["acc"][:, 0] = np.arange(n)
    sensor = RecordedSensor("imu", records["t"].copy(), records)
    source = ReplaySource(sensor, ReplayTimeline(1000.0, sensor.t[-1].item()))
    source.start(50.0)
    t, got = source.poll(50.0)
    assert got["acc"][:, 0].tolist() == [0.0] and t.tolist() == [50.0]
    t, got = source.poll(62.0)  # 12 s later: the last 5 s of them, not 12 s at once
    assert len(t) == int(MAX_CATCH_UP_S * 100) + 1
    assert got["acc"][-1, 0] == 1200.0 and t[-1] == pytest.approx(62.0)
    assert np.diff(t) == pytest.approx(0.01)
    assert source.timeline.finished(71.0) and not source.timeline.finished(69.0)


ORIGINAL = {line.split()[0]: bytes.fromhex(line.split(None, 1)[1]) for line in (
    DATA / "ros4mat" / "original_client.hex"
).read_text().splitlines() if line.strip() and not line.startswith("#")}  # fmt: skip
"""The original ros4mat MATLAB client's requests, as captured."""


def holding(subscribe: bytes, samples: int) -> bytes:
    """The original client's SUBSCRIBE with a buffer of ``samples`` instead of its 100 (0.2 s
    of the recorded 500 Hz ADC: a loaded machine that holds the test's thread back longer
    loses samples, as that client would); every other byte is the captured one."""
    from robocli.protocols import ros4mat as r4m

    msg = r4m.decode(subscribe)
    body = {**msg.body, "buffer_size": max(samples, msg.body["buffer_size"])}
    patched = r4m.encode_request(r4m.MsgType.SUBSCRIBE, body, client_id=msg.client_id)
    changed = [i for i, (a, b) in enumerate(zip(subscribe, patched, strict=True)) if a != b]
    assert not changed or changed[-1] - changed[0] < 4  # one u32 field
    return patched


def test_the_original_clients_bytes_get_the_recorded_adc(
        recording: tuple[Path, dict[str, Pulled]], replay_hub: HubServer) -> None:  # fmt: skip
    import socket

    from robocli.protocols import ros4mat as r4m

    def exact(sock: socket.socket, n: int) -> bytes:
        buf = bytearray()
        while len(buf) < n:
            chunk = sock.recv(n - len(buf))
            assert chunk, "the hub closed the connection"
            buf += chunk
        return bytes(buf)

    def ask(sock: socket.socket, request: bytes) -> Any:
        sock.sendall(request)
        head = exact(sock, r4m.HEADER_SIZE)
        return r4m.decode(head + exact(sock, r4m.body_length(r4m.Header.parse(head))))

    _, pulled = recording
    rec_data, rec_t = pulled["adc"].arrays()
    samples: list[dict[str, Any]] = []
    subscribe = holding(ORIGINAL["subscribe_adc"], len(rec_t))
    with socket.create_connection(("127.0.0.1", replay_hub.port), timeout=30) as sock:
        assert ask(sock, ORIGINAL["connect"]).error == 0
        assert ask(sock, subscribe).error == 0  # its 100 Hz: ignored

        def pulled_all() -> bool:
            samples.extend(ask(sock, ORIGINAL["pull_adc"]).body or [])
            return len(samples) >= len(rec_t)

        wait_for(pulled_all, what="every recorded ADC sample")
        sock.sendall(ORIGINAL["quit"])
    t = np.array([s["t"] for s in samples])
    channels = np.array([s["channels"] for s in samples], dtype=np.float32).T
    assert np.array_equal(channels, rec_data.astype(np.float32))  # the recorded 500 Hz ADC
    assert np.diff(t) == pytest.approx(np.diff(rec_t), abs=2e-6)
