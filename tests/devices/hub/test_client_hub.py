"""The hub client against the built-in hub over real sockets: every sensor in the original
client's shapes, many clients, compression, alignment, clock offset, reconnects."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest

from robocli import Hub
from robocli.devices.hub.client import subscribe_body
from robocli.errors import DeviceError, InvalidArgument, ProtocolError, TransportError
from robocli.hub_server import HubServer
from robocli.protocols.ros4mat import MsgType, encode_request
from tests.waiting import wait_for

# sensor -> (subscribe arguments, the hub's name, expected data shape without N)
SENSORS: dict[str, tuple[dict[str, Any], str, tuple[int, ...]]] = {
    "adc": ({"rate": 200}, "adc", (8,)),
    "imu": ({"rate": 100}, "imu", (9,)),
    "gps": ({"rate": 5}, "gps", (7,)),
    "battery": ({"rate": 10}, "battery", (13,)),
    "computer": ({"rate": 10}, "sysinfo", (15,)),
    "hokuyo": ({"rate": 40}, "laser", (1081,)),
    "camera": ({"rate": 30, "resolution": "320x240"}, "camera", (240, 320, 3)),
    "camera_stereo": ({"rate": 15, "resolution": "320x240"}, "stereo", (240, 320, 3)),
    "kinect": ({"rate": 15, "resolution": "320x240"}, "depth", (240, 320, 3)),
}


@pytest.fixture(scope="module")
def server() -> Iterator[HubServer]:
    with HubServer(bind="127.0.0.1", port=0, sim=True) as srv:
        yield srv


@pytest.fixture
def hub(server: HubServer) -> Iterator[Hub]:
    with Hub.connect("127.0.0.1", server.port) as client:
        yield client


def samples_of(read: Callable[[], Any], n: int, timeout: float = 10.0) -> list[Any]:
    """Readings until they hold ``n`` samples in all (``timeout`` bounds a failure)."""
    got: list[Any] = []

    def enough() -> bool:  # reads back to back while samples come, as a client would
        while len(reading := read()):
            got.append(reading)
            if sum(len(r) for r in got) >= n:
                return True
        return False

    wait_for(enough, f"{n} samples", timeout=timeout)
    return got


@pytest.mark.parametrize("name", list(SENSORS))
def test_every_sensor_in_the_original_shapes(server: HubServer, hub: Hub, name: str) -> None:
    kwargs, hub_name, shape = SENSORS[name]
    if hub_name not in server.sensors:
        pytest.skip(f"this hub does not serve {hub_name} yet")
    hub.subscribe(name, **kwargs)
    reading = samples_of(lambda: hub.read(name), 2)[0]
    data, t = reading
    assert data.shape[:-1] == shape and data.shape[-1] == len(t) == len(reading) >= 1
    assert np.all(np.diff(t) > 0) and np.isfinite(t).all()
    assert abs(t[-1] - time.time()) < 5.0  # client clock, acquisition times
    if name == "imu":
        assert reading.accel.shape == (3, len(t))
        assert abs(np.linalg.norm(reading.accel, axis=0).mean() - 1.0) < 0.2  # about 1 g
    if name == "gps":
        assert (np.abs(reading.longitude) <= 180).all() and (np.abs(reading.latitude) <= 90).all()
    if name == "hokuyo":
        assert reading.info is not None and reading.info.shape == (6,)
    if name == "kinect":
        assert reading.depth.shape == (240, 320, len(t)) and reading.depth.dtype == np.uint16
    hub.unsubscribe(name)


def test_pull_is_destructive_and_cursors_independent(server: HubServer) -> None:
    with Hub.connect("127.0.0.1", server.port) as a, Hub.connect("127.0.0.1", server.port) as b:
        a.subscribe("adc", 500)
        b.subscribe("adc")  # silent: joins the current settings
        b_joined = server.hub.clock()  # b's buffer fills from here (or a little before)
        # a consumes until it holds samples acquired after b joined (under load, a's first
        # pull can hold only samples from before b's subscription was registered)
        pulls_a: list[Any] = []

        def a_is_past_b_joining() -> bool:
            pulls_a.append(a.read("adc"))
            return len(pulls_a[-1]) > 0 and pulls_a[-1].hub_t[-1] > b_joined + 0.05

        wait_for(a_is_past_b_joining, "a past the time b joined", timeout=30)
        more_a = samples_of(lambda: a.read("adc"), 1)
        all_b = samples_of(lambda: b.read("adc"), 30)
        ta = np.concatenate([r.hub_t for r in pulls_a + more_a])
        tb = np.concatenate([r.hub_t for r in all_b])
        assert np.all(np.diff(ta) > 0) and np.all(np.diff(tb) > 0)  # nothing twice for a
        # b's pull still had what a had consumed: cursors are per client
        consumed_by_a = np.concatenate([r.hub_t for r in pulls_a])
        assert len(np.intersect1d(consumed_by_a, tb)) > 0


def test_many_clients_at_once(server: HubServer) -> None:
    n_clients = 12
    errors: list[BaseException] = []
    counts = [0] * n_clients

    def client(i: int) -> None:
        try:
            with Hub.connect("127.0.0.1", server.port) as h:
                h.subscribe("imu", 100) if i == 0 else h.subscribe("imu", 100, buffer=500)
                got = samples_of(lambda: h.read("imu"), 20, timeout=30)
                counts[i] = sum(len(r) for r in got)
                # the hub's times: Reading.t is on this client's clock through an offset
                # that each pull may refine (by up to half a round trip, long under load)
                t = np.concatenate([r.hub_t for r in got])
                assert np.all(np.diff(t) > 0)
        except BaseException as exc:
            errors.append(exc)

    threads = [threading.Thread(target=client, args=(i,)) for i in range(n_clients)]
    for th in threads:
        th.start()
    for th in threads:
        th.join(60)
    assert not errors, errors[0]
    assert min(counts) >= 20


def test_compression_gives_the_same_readings(server: HubServer) -> None:
    with Hub.connect("127.0.0.1", server.port, compress=True) as h:
        h.subscribe("adc", 200)
        frame = wait_for(lambda: f if (f := h.pull("adc"))[6] or f[7] else b"",  # size > 0
                         "a frame with samples")  # fmt: skip
        assert frame[18] == 1  # compressionType zlib
        reading = samples_of(lambda: h.read("adc"), 5)[0]
        assert reading.data.shape[0] == 8 and reading.data.dtype == np.float32


def test_read_aligned(server: HubServer, hub: Hub) -> None:
    hub.subscribe("adc", 500)
    hub.subscribe("imu", 100)
    time.sleep(0.3)
    out = hub.read_aligned(["adc", "imu"], rate=50)
    t = out["t"]
    assert len(t) >= 5 and np.allclose(np.diff(t), 0.02, atol=1e-6)
    assert out["adc"].shape == (8, len(t)) and out["imu"].shape == (9, len(t))
    assert np.isfinite(out["adc"]).all() and np.isfinite(out["imu"]).all()
    time.sleep(0.2)
    ref = hub.read_aligned(["adc", "imu"], reference="imu")
    assert ref["imu"].shape[1] == len(ref["t"]) and ref["adc"].shape == (8, len(ref["t"]))
    with pytest.raises(InvalidArgument, match="rate or reference"):
        hub.read_aligned(["adc"], rate=10, reference="adc")
    for names in ([], "adc"):
        with pytest.raises(InvalidArgument, match="list of sensor names"):
            hub.read_aligned(names, rate=10)  # type: ignore[arg-type]


def test_clock_offset_within_half_a_millisecond(server: HubServer) -> None:
    injected = 123.456789  # the client's clock runs this far ahead of the hub's
    with Hub.connect("127.0.0.1", server.port, clock=lambda: time.time() + injected) as h:
        h.subscribe("adc", 100)
        for _ in range(40):
            h.read("adc")
        assert h.clock_offset is not None
        assert abs(h.clock_offset - (-injected)) <= 0.5e-3
        # the times follow the estimate by slewing (1 % of hub time): they get there
        deadline = time.monotonic() + 30.0
        while True:
            reading = samples_of(lambda: h.read("adc"), 1)[-1]
            if np.abs(reading.t - reading.hub_t - injected).max() <= 0.5e-3:
                break
            assert time.monotonic() < deadline, reading.t[-1] - reading.hub_t[-1] - injected
    with Hub.connect("127.0.0.1", server.port, hub_clock=True) as h:
        h.subscribe("adc", 100)
        reading = samples_of(lambda: h.read("adc"), 1)[0]
        assert (reading.t == reading.hub_t).all()


def test_reconnect_keeps_buffers(server: HubServer) -> None:
    h = Hub.connect("127.0.0.1", server.port)
    h.subscribe("adc", 200)
    samples_of(lambda: h.read("adc"), 1)
    cid = h.client_id
    h.close(stop=False)
    time.sleep(0.1)
    with Hub.connect("127.0.0.1", server.port, client_id=cid) as again:
        assert again.client_id == cid
        reading = again.read("adc")  # what accumulated while we were away
        assert len(reading) >= 5


def test_unsubscribe_digital_out_and_refusals(server: HubServer, hub: Hub) -> None:
    hub.subscribe("adc", 100)
    hub.digital_out(1, 0, 1, 1)
    hub.read("adc")  # a round trip after DOUT_CTRL, which has no reply
    assert server.sensors["adc"]["digital_out"] == [1, 0, 1, 1]
    hub.unsubscribe("adc")
    data, t = hub.read("adc")  # not subscribed: empty, as the original server answers
    assert data.shape == (8, 0) and len(t) == 0
    with pytest.raises(InvalidArgument, match="rate"):
        hub.subscribe("adc", 0)
    with pytest.raises(InvalidArgument, match="channels"):  # as `--channels 0`
        hub.subscribe("adc", 100, channels=0)
    with pytest.raises(InvalidArgument, match="kinect"):  # 0x28: ros4mat has no pull for it
        hub.subscribe("kinect_ir", 10)


def test_no_hub_is_a_transport_error() -> None:
    with pytest.raises(TransportError, match=r"no hub at 127\.0\.0\.1:1 .*robocli serve --sim"):
        Hub.connect("127.0.0.1", 1, timeout=2.0)


def test_samples_the_hub_dropped_for_a_small_buffer_are_counted(server: HubServer) -> None:
    """ros4mat does not say what the hub dropped: the client counts the gaps in the sample
    times, per reading and per sensor, the ones before the first sample included."""
    with Hub.connect("127.0.0.1", server.port) as h:
        h.subscribe("adc", 1000, buffer=10)
        readings = []
        for _ in range(3):
            time.sleep(0.3)  # pulls far apart, so that the buffer of 10 overflows between them
            readings.append(samples_of(lambda: h.read("adc"), 1)[0])
        assert sum(len(r) for r in readings) <= 30
        assert sum(r.lost for r in readings) == h.lost["adc"]
        assert readings[0].lost > 100  # about 300 acquired before the first pull, 10 kept
        for before, after in zip(readings[:-1], readings[1:], strict=True):  # gaps in hub times
            assert after.lost == round((after.hub_t[0] - before.hub_t[-1]) * 1000) - 1 > 100
        h.subscribe("imu", 200)  # a buffer of 1 s, pulled often: nothing lost
        for _ in range(10):
            time.sleep(0.05)
            assert h.read("imu").lost == 0
        assert "imu" not in h.lost


def test_a_refusal_names_the_request(server: HubServer, hub: Hub) -> None:
    with pytest.raises(DeviceError, match=r"^hub refused SUBSCRIBE: silent subscribe"):
        hub.subscribe("gps")  # silent, and nobody runs it


def test_the_token_of_a_hub_that_has_one() -> None:
    """``token=`` goes after CONNECT's 2-byte body: with it settings change; without it,
    or with a wrong one, the hub says "unauthorized" (pulls and silent subscribes work)."""
    with HubServer(bind="127.0.0.1", port=0, sim=True, token=b"s3cret") as srv:
        with Hub.connect("127.0.0.1", srv.port, token="s3cret") as owner:
            owner.subscribe("adc", 200)
            assert len(samples_of(lambda: owner.read("adc"), 2))
            for token in (None, b"guess"):
                with Hub.connect("127.0.0.1", srv.port, token=token) as other:
                    with pytest.raises(DeviceError, match="unauthorized"):
                        other.subscribe("adc", 100)
                    other.subscribe("adc")  # silent: joins, changes nothing
                    assert len(samples_of(lambda o=other: o.read("adc"), 2))
    for bad in (b"", "x" * 5000):
        with pytest.raises(InvalidArgument, match="token"):
            Hub.connect("127.0.0.1", srv.port, token=bad)


def test_a_full_hub_says_so() -> None:
    with HubServer(bind="127.0.0.1", port=0, sim=True, max_clients=1) as srv:
        with Hub.connect("127.0.0.1", srv.port) as first:
            with pytest.raises(DeviceError, match="too many clients"):
                Hub.connect("127.0.0.1", srv.port)
            first.subscribe("adc", 100)  # the first client is not disturbed


def test_raw_camera_buffers_fit_one_reply(server: HubServer) -> None:
    with Hub.connect("127.0.0.1", server.port, timeout=1.0) as h:
        h.subscribe("camera", rate=30, resolution="640x480")  # 1 s would be 27 MB: 18 frames
        with pytest.raises(InvalidArgument, match="at most 18"):
            h.subscribe("camera", rate=30, resolution="640x480", buffer=30)
        # a hub that sends more than a reply may carry: one typed error, the link is closed
        body = subscribe_body("camera", 30, resolution="640x480")  # buffer 30, bytes as sent
        ack = h.session.request(
            encode_request(MsgType.SUBSCRIBE, body, client_id=h.client_id),
            lambda f: f[0] == MsgType.SUBSCRIBE_ACK,
            5.0,
        )
        assert ack[1] == 0
        got = samples_of(lambda: h.read("camera"), 1)  # drain, then let 30 frames pile up
        assert got[0].data.shape[:3] == (480, 640, 3)
        time.sleep(1.3)
        with pytest.raises(ProtocolError, match="exceeds 16 MiB"):
            h.read("camera")
        with pytest.raises(ProtocolError):
            h.read("adc")


def test_read_aligned_on_camera_frames(server: HubServer, hub: Hub) -> None:
    hub.subscribe("imu", 200)
    hub.subscribe("camera", rate=30, resolution="320x240")
    hub.subscribe("hokuyo", 40)
    samples_of(lambda: hub.read("camera"), 1, 30)  # start from now
    ring = server.hub.channel("camera").ring
    assert ring is not None
    pushed = ring.pushed
    wait_for(lambda: ring.pushed >= pushed + 3, "frames to align", timeout=30)  # not a fixed sleep
    out = hub.read_aligned(["camera", "imu", "hokuyo"], reference="camera")
    m = len(out["t"])
    assert m >= 2 and out["camera"].shape == (240, 320, 3, m)
    assert out["imu"].shape == (9, m) and out["hokuyo"].shape == (1081, m)
    scans = out["hokuyo"][:, np.isfinite(out["hokuyo"][0])]
    assert scans.dtype == np.float32  # nearest scans, not interpolated between scans


@pytest.mark.parametrize("name", ["camera", "camera_stereo"])
def test_jpeg_frames_decode_to_the_scene_of_their_time(server: HubServer, name: str) -> None:
    """quality > 0: the hub encodes each frame as JPEG (Pillow, a test dependency), and the
    client decodes it back into the scene that the hub rendered at that frame's timestamp."""
    from robocli.hub_server.sources.imaging import StereoSource, scene

    assert server.sensors["camera"]["jpeg"] == "pillow"
    with Hub.connect("127.0.0.1", server.port) as hub:
        hub.subscribe(name, rate=15, resolution="160x120", quality=90)
        reading = samples_of(lambda: hub.read(name), 2)[0]
        hub.unsubscribe(name)
    data, t = reading
    assert data.shape[:3] == (120, 160, 3) and data.dtype == np.uint8
    frame, ti = data[..., -1].astype(float), float(t[-1])

    def error(shift_s: float, disparity: int = 0) -> float:
        return float(np.abs(frame - scene(160, 120, ti + shift_s, disparity)).mean())

    assert error(0.0) < 3.0  # JPEG at quality 90: a few levels off on average
    assert error(0.5) > 3 * error(0.0)  # and it is this frame, not any frame
    if name == "camera_stereo":
        right = reading.right[..., -1].astype(float)
        want = scene(160, 120, ti, StereoSource.DISPARITY)
        assert np.abs(right - want).mean() < 3.0


def test_kinect_jpeg_readings_of_several_frames(server: HubServer) -> None:
    """The hub's Kinect RGB frames in JPEG differ in size: a reading of several decodes."""
    from robocli.hub_server.sources.imaging import scene

    with Hub.connect("127.0.0.1", server.port) as hub:
        hub.subscribe("kinect", rate=30, resolution="160x120", quality=90)
        deadline = time.monotonic() + 30.0
        while len(reading := hub.read("kinect")) < 3:
            assert time.monotonic() < deadline, "no reading of 3 frames"
            time.sleep(0.05 * (1 + len(reading)))  # let frames pile up between pulls
        hub.unsubscribe("kinect")
    assert reading.rgb.shape == (120, 160, 3, len(reading))
    assert reading.depth.shape == (120, 160, len(reading)) and reading.depth.max() > 0
    for i in (0, -1):
        want = scene(160, 120, float(reading.hub_t[i]))
        assert np.abs(reading.rgb[..., i].astype(float) - want).mean() < 3.0


def test_a_refused_digital_out_raises() -> None:
    """DOUT_CTRL has no reply in ros4mat, but robocli's hub answers a refusal: a client
    without the hub's token hears "unauthorized" from digital_out itself, the outputs stay
    as they were, and the link goes on."""
    with HubServer(bind="127.0.0.1", port=0, sim=True, token=b"s3cret") as srv:
        with Hub.connect("127.0.0.1", srv.port, token="s3cret") as owner:
            assert owner.answers_refusals
            owner.subscribe("adc", 100)
            owner.digital_out(1, 1, 0, 1)  # fenced: the hub has handled it on return
            assert srv.sensors["adc"]["digital_out"] == [1, 1, 0, 1]
            for token in (None, b"guess"):
                with Hub.connect("127.0.0.1", srv.port, token=token) as other:
                    with pytest.raises(DeviceError, match=r"refused DOUT_CTRL: unauthorized"):
                        other.digital_out(0, 0, 0, 0)
                    other.subscribe("adc")  # the link goes on: silent subscribe, a pull
                    assert len(samples_of(lambda o=other: o.read("adc"), 1))
            assert srv.sensors["adc"]["digital_out"] == [1, 1, 0, 1]


class ScriptedClock:
    """The client's clock (time.time), except for the exchange after :meth:`shift`: both
    its times read ``x`` s early, as a pull with no round trip whose offset sample is ``x``
    s off. The real estimator takes it (the fastest round trip) and jumps by ``x``."""

    def __init__(self) -> None:
        self._fake: list[float] = []
        self._pending: float | None = None

    def shift(self, x: float) -> None:
        self._pending = x

    def __call__(self) -> float:
        if self._fake:
            return self._fake.pop()
        if self._pending is not None:
            t = time.time() - self._pending
            self._pending = None
            self._fake.append(t)  # the same time after the reply: a zero round trip
            return t
        return time.time()


def test_sample_times_never_step_back_when_the_offset_estimate_moves(server: HubServer) -> None:
    """The offset estimate jumps 0.5 s (hub clock further ahead) and later 1 s back: the
    sample times of successive reads keep increasing; the mapping slews toward the new
    estimate at most 1 % of hub time."""
    from robocli.devices.hub.client import CLOCK_SLEW

    clock = ScriptedClock()
    with Hub.connect("127.0.0.1", server.port, clock=clock) as h:
        h.subscribe("adc", 1000)
        readings = samples_of(lambda: h.read("adc"), 20)
        before = h.clock_offset
        assert before is not None
        h0, applied0 = readings[-1].hub_t[-1], readings[-1].hub_t[-1] - readings[-1].t[-1]
        clock.shift(0.5)
        readings += samples_of(lambda: h.read("adc"), 50)
        after = h.clock_offset
        assert after is not None and after - before == pytest.approx(0.5, abs=0.05)
        assert_increasing(readings)
        h1, applied1 = readings[-1].hub_t[-1], readings[-1].hub_t[-1] - readings[-1].t[-1]
        assert 0 < applied1 - applied0 <= CLOCK_SLEW * (h1 - h0) + 1e-6  # slewing toward it
        clock.shift(-1.0)  # and the other way: times jump forward, never back
        readings += samples_of(lambda: h.read("adc"), 50)
        assert h.clock_offset is not None and h.clock_offset < before - 0.4
    steps, hub_steps = assert_increasing(readings)
    spacing = steps[hub_steps < 0.0015]  # consecutive samples (1 ms apart)
    assert np.all(spacing > 0.001 * (1 - CLOCK_SLEW) - 1e-6)


def assert_increasing(readings: list[Any]) -> tuple[Any, Any]:
    """The client times of successive readings keep increasing (as their hub times do)."""
    hub_steps = np.diff(np.concatenate([r.hub_t for r in readings]))
    steps = np.diff(np.concatenate([r.t for r in readings]))
    assert np.all(hub_steps > 0)
    assert np.all(steps > 0), f"times stepped back by {-steps.min():.6f} s"
    return steps, hub_steps
