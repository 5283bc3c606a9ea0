"""The hub's Zenoh front-end and :class:`ZenohHub`, in one process over loopback: the same
arrays as over ros4mat TCP, history for late joiners, gaps counted, the settings queryable
under the token, the batch encoding a non-robocli program can read."""

from __future__ import annotations

import json
import math
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robocli.devices.hub.client import Hub
from robocli.devices.hub.over_zenoh import HUB_NAMES, ZenohHub, alive
from robocli.errors import DeviceError, InvalidArgument, ProtocolError, TransportError
from robocli.hub_server import HubServer
from robocli.hub_server.frontends.ros4mat import SENSOR_IDS
from robocli.hub_server.frontends.zenoh import ZenohFrontend
from robocli.protocols.ros4mat import MsgType
from robocli.zenoh import open_session
from robocli.zenoh.batch import BATCH_HEADER, decode_batch, encode_head
from robocli.zenoh.session import close_session
from tests.waiting import wait_for

pytest.importorskip("zenoh", reason="needs robocli-robots[zenoh] (eclipse-zenoh)")

DEADLINE_S = 30.0


class Lab:
    """A simulated hub with its ros4mat listener and its Zenoh front-end on ``endpoint``."""

    def __init__(self, endpoint: str, token: bytes | None = None, **publish: Any) -> None:
        self.endpoint = endpoint
        self.server = HubServer(port=0, sim=True, token=token).start()
        self.session = open_session(endpoint, "server")
        self.front = ZenohFrontend(self.server.hub, self.session, "lab", token=token,
                                   publish=publish).start()  # fmt: skip

    def close(self) -> None:
        self.front.close()
        close_session(self.session)
        self.server.close()

    def published(self, sensor: str) -> int:
        """Samples put so far on ``sensor``."""
        return int(self.front.info()["sensors"][sensor]["next_seq"])


@pytest.fixture
def lab(endpoint: str) -> Iterator[Lab]:
    lab = Lab(endpoint, adc={"freq_acquisition": 1000})
    try:
        yield lab
    finally:
        lab.close()


def read_some(hub: Hub, sensor: str, n: int = 3) -> Any:
    """A reading of at least ``n`` samples (reads appended until then)."""
    got: list[Any] = []

    def enough() -> bool:
        got.append(hub.read(sensor))
        return sum(len(r) for r in got) >= n

    wait_for(enough, f"{n} samples of {sensor}")
    return [r for r in got if len(r)]


def test_names_match_the_hubs() -> None:
    assert {int(k): v for k, v in HUB_NAMES.items()} == {int(k): v for k, v in SENSOR_IDS.items()}


@pytest.mark.parametrize(
    ("sensor", "rate", "params"),
    [("adc", 1000, {}), ("imu", 200, {}), ("gps", 5, {}), ("battery", 2, {}),
     ("camera", 15, {"quality": 80}), ("camera", 15, {}), ("stereo", 5, {}), ("laser", 10, {}),
     ("depth", 5, {})],
)  # fmt: skip
def test_arrays_match_ros4mat(lab: Lab, sensor: str, rate: int, params: dict[str, Any]) -> None:
    if params.get("quality"):
        pytest.importorskip("PIL")
    tcp = Hub.connect(lab.server.url)
    zh = ZenohHub.connect("lab", zenoh=lab.endpoint)
    try:
        tcp.subscribe(sensor, rate, **params)
        zh.subscribe(sensor, rate, **params)
        ours, theirs = read_some(zh, sensor, 2)[0], read_some(tcp, sensor, 2)[0]
        assert ours.data.shape[:-1] == theirs.data.shape[:-1]
        assert ours.data.dtype == theirs.data.dtype and ours.t.dtype == theirs.t.dtype
        assert ours.t.shape == (ours.data.shape[-1],) and ours.hub_t.shape == ours.t.shape
        assert sorted(ours.fields) == sorted(theirs.fields)
        for name in ours.fields:
            a, b = getattr(ours, name), getattr(theirs, name)
            assert a.shape[:-1] == b.shape[:-1] and a.dtype == b.dtype, name
        # the same samples, whichever the front-end: acquisition times on one grid
        common = np.intersect1d(ours.hub_t, np.concatenate([r.hub_t for r in [theirs]]))
        assert abs(ours.t[-1] - time.time()) < 5.0  # on this machine's clock
        if len(common):
            i, j = np.searchsorted(ours.hub_t, common[0]), np.searchsorted(theirs.hub_t, common[0])
            assert np.array_equal(ours.data[..., i], theirs.data[..., j], equal_nan=True)
    finally:
        zh.close()
        tcp.close()


def test_late_joiner_gets_history(lab: Lab) -> None:
    wait_for(lambda: lab.published("adc") >= 1000, "a second of adc published")
    joined = lab.server.hub.clock()
    with ZenohHub.connect("lab", zenoh=lab.endpoint) as zh:
        # join what is published, with the hub's recent history; a buffer of 10 s, so that a
        # slow first read (a loaded machine) overflows nothing and a gap can only be a real one
        zh.subscribe("adc", buffer=10_000)
        first = read_some(zh, "adc", 100)
        t = np.concatenate([r.hub_t for r in first])
        assert t[0] < joined - 0.2  # samples acquired before this client existed
        assert np.all(np.diff(t) > 0)  # in order, no duplicate
        assert zh.lost == {}


def test_gap_is_detected_and_counted(lab: Lab) -> None:
    with ZenohHub.connect("lab", zenoh=lab.endpoint) as zh:
        zh.subscribe("adc", buffer=100_000)
        read_some(zh, "adc", 10)
        lab.front._ticker.close()  # the hub stops publishing: its own cursor overflows
        state = lab.front._state
        assert state is not None
        wait_for(lambda: lab.server.hub.dropped(state, "adc") > 0, "the hub's cursor overflow")
        dropped = lab.server.hub.dropped(state, "adc")
        lab.front._tick(0.0)  # publishing again: the next batch follows a gap
        got: list[Any] = []

        def gap_read() -> bool:  # batches put before the stop may still be on their way
            got.append(zh.read("adc"))
            return sum(r.lost for r in got) > 0

        wait_for(gap_read, "the batch after the gap")
        readings = [r for r in got if len(r)]
        lost = sum(r.lost for r in got)
        assert lost >= dropped > 0
        assert zh.lost["adc"] == lost
        t = np.concatenate([r.hub_t for r in readings])
        assert len(t) and np.all(np.diff(t) > 0)


def test_settings_refused_without_the_token(endpoint: str) -> None:
    lab = Lab(endpoint, token=b"s3cret", adc=None)
    try:
        with ZenohHub.connect("lab", zenoh=endpoint) as zh:
            with pytest.raises(DeviceError, match="unauthorized"):
                zh.subscribe("imu", 200)
            assert lab.front.refused == 1
            assert not lab.front.info()["sensors"]["imu"]["published"]
            zh.subscribe("adc")  # joining what is published needs no token
            assert len(read_some(zh, "adc", 1)[0])
        with ZenohHub.connect("lab", zenoh=endpoint, token="s3cret") as zh:
            zh.subscribe("imu", 200)
            assert lab.server.sensors["imu"]["rate"] == 200
            assert len(read_some(zh, "imu", 1)[0])
    finally:
        lab.close()


def test_info_and_encoding_readable_without_robocli(lab: Lab) -> None:
    """A plain Zenoh program: the @info JSON, and a batch decoded from the README's
    description alone (header, then 40-byte ADC records: 8 float32 volts, float64 t)."""
    client = open_session(lab.endpoint, "client")
    try:
        replies = list(client.get("robocli/lab/@info", timeout=10))
        info = json.loads(replies[0].ok.payload.to_bytes())
        adc = info["sensors"]["adc"]
        assert adc["published"] and adc["rate"] == 1000 and adc["key"] == "robocli/lab/adc"
        got: list[Any] = []
        sub = client.declare_subscriber("robocli/lab/adc", got.append)
        wait_for(lambda: got, "a batch")
        sub.undeclare()
        sample = got[0]
        assert str(sample.encoding) == "application/octet-stream;robocli.batch.v1;sensor=adc"
        raw = sample.payload.to_bytes()
        magic, version, sensor, head, first, count, size, _stamp = BATCH_HEADER.unpack_from(raw)
        assert (magic, version, sensor, head) == (b"RCZB", 1, MsgType.ADC, 32)
        rec = np.frombuffer(raw, dtype=[("v", "<f4", 8), ("t", "<f8")], offset=head)
        assert len(rec) == count and size == 40 * count
        assert np.diff(rec["t"]) == pytest.approx(np.full(count - 1, 1e-3), abs=1e-6)
    finally:
        close_session(client)


def test_batch_decoding_refuses_what_is_not_one() -> None:
    good = encode_head(MsgType.ADC, 5, 1, 40, 1.0) + bytes(40)
    assert decode_batch(good).end == 6
    for bad in (good[:20], b"XXXX" + good[4:], good + b"x", good[:-1]):
        with pytest.raises(ProtocolError):
            decode_batch(bad)


def test_batch_decoding_bounds_the_sample_count_by_the_body() -> None:
    """A header claiming 2^32-1 samples in a body of one; an IMU body too short; an
    unknown sensor; a stamp that is no time."""
    for bad in (encode_head(MsgType.ADC, 0, 0xFFFFFFFF, 40, 1.0) + bytes(40),
                encode_head(MsgType.IMU, 0, 2, 44, 1.0) + bytes(44),
                encode_head(0x10, 0, 1, 40, 1.0) + bytes(40),
                encode_head(MsgType.ADC, 0, 1, 40, float("nan")) + bytes(40),
                encode_head(MsgType.WEBCAM, 0, 2, 22, 1.0) + bytes(22)):  # fmt: skip
        with pytest.raises(ProtocolError):
            decode_batch(bad)
    assert decode_batch(encode_head(MsgType.WEBCAM, 0, 1, 30, 1.0) + bytes(30)).count == 1


@settings(max_examples=300, deadline=None)
@given(sensor=st.sampled_from([*SENSOR_IDS, 0, 0x10, 0xFF]), first=st.integers(0, 2**64 - 1),
       count=st.integers(0, 8) | st.integers(0, 2**32 - 1), stamp=st.floats(),
       body=st.binary(max_size=200))  # fmt: skip
def test_batch_decoding_raises_protocol_errors_only(
    sensor: int, first: int, count: int, stamp: float, body: bytes
) -> None:
    """Any header over any body: a batch whose samples fit its body, or a ProtocolError."""
    try:
        batch = decode_batch(encode_head(sensor, first, count, len(body), stamp) + body)
    except ProtocolError:
        return
    assert batch.count * 22 <= len(batch.body)  # 22 bytes: the smallest record
    assert math.isfinite(batch.stamp)


def test_a_reader_drops_and_counts_batches_that_cannot_be_its_hubs(lab: Lab) -> None:
    """Without a lab's ACL anyone may put on the hub's keys (with it, the router drops
    them: test_lab_acl.py): what cannot be the hub's batch is counted, never read."""
    with ZenohHub.connect("lab", zenoh=lab.endpoint) as zh:
        zh.subscribe("adc")
        got = read_some(zh, "adc", 10)
        forger = open_session(lab.endpoint, "client")
        try:
            now, record = lab.server.hub.clock(), np.zeros(1, [("v", "<f4", 8), ("t", "<f8")])
            record["v"], record["t"] = 1234.5, now
            body = record.tobytes()
            for head in (encode_head(MsgType.ADC, 0, 0xFFFFFFFF, 40, now),  # 2^32-1 samples
                         encode_head(MsgType.ADC, 1 << 40, 1, 40, now + 0.01),  # a 2^40 gap
                         encode_head(MsgType.IMU, 0, 1, 40, now)):  # another sensor  # fmt: skip
                forger.put("robocli/lab/adc", head + body)
            forger.put("robocli/lab/adc", b"not a batch")

            def rejected() -> bool:
                got.append(zh.read("adc"))
                return zh.rejected.get("adc", 0) >= 4

            wait_for(rejected, "4 batches rejected")
        finally:
            close_session(forger)
        got += read_some(zh, "adc", 10)
        assert not any(np.isclose(r.data, 1234.5).any() for r in got)
        assert sum(r.lost for r in got) < 1000 and zh.lost.get("adc", 0) < 1000


def test_a_settings_query_that_does_not_decode_gets_an_error_reply(lab: Lab) -> None:
    session = open_session(lab.endpoint, "client")
    try:
        for bad in (b"[" * 100_000, b'{"params": {"channels": 1e400}}', b"{" + b"1" * 400):
            replies = list(session.get("robocli/lab/@settings/adc", payload=bad,
                                       timeout=DEADLINE_S))  # fmt: skip
            assert len(replies) == 1 and replies[0].err is not None, bad[:20]
            assert "error" in json.loads(replies[0].err.payload.to_bytes())
    finally:
        close_session(session)
    assert lab.front.refused == 3


def test_a_reply_that_does_not_decode_is_a_protocol_error(endpoint: str) -> None:
    """Something answering a hub's @info with 100,000 '[' (a RecursionError in the reader
    before), then its @settings with an error that is no JSON."""
    server = open_session(endpoint, "server")
    info = server.declare_queryable("robocli/fake/@info",
                                    lambda q: q.reply(q.key_expr, b"[" * 100_000))  # fmt: skip
    try:
        with pytest.raises(ProtocolError, match="nested too deeply"):
            ZenohHub.connect("fake", zenoh=endpoint)
    finally:
        info.undeclare()
    server.declare_queryable("robocli/fake/@info", lambda q: q.reply(q.key_expr, b"{}"))
    server.declare_queryable("robocli/fake/@settings/*", lambda q: q.reply_err(b"[" * 100_000))
    try:
        with ZenohHub.connect("fake", zenoh=endpoint) as zh:
            with pytest.raises(DeviceError, match=r"refused: \[\[\["):
                zh.subscribe("adc", 100)
    finally:
        close_session(server)


def test_a_sensor_a_ros4mat_client_starts_is_published_while_it_runs(lab: Lab) -> None:
    def published(sensor: str) -> bool:
        return bool(lab.front.info()["sensors"][sensor]["published"])

    assert not published("laser")
    tcp = Hub.connect(lab.server.url)
    tcp.subscribe("laser", 10)
    wait_for(lambda: published("laser"), "laser published")
    with ZenohHub.connect("lab", zenoh=lab.endpoint) as zh:
        zh.subscribe("laser")  # silent: joins what the ros4mat client started
        assert read_some(zh, "laser", 1)[0].data.shape[0] == 1081
        tcp.close()  # QUIT: nobody else keeps the laser running
        wait_for(lambda: not published("laser"), "laser no longer published")
        wait_for(lambda: not lab.server.sensors["laser"]["active"], "the laser stopped")


def test_a_restarted_hub_is_read_again(lab: Lab) -> None:
    """A new hub process numbers its samples from 0 again: its batches are new samples,
    not duplicates of the old ones."""
    with ZenohHub.connect("lab", zenoh=lab.endpoint) as zh:
        zh.subscribe("adc")
        wait_for(lambda: sum(len(r) for r in read_some(zh, "adc", 1000)), "a second of adc read")
        lab.front.close()  # the hub goes; another starts under the same name
        lab.front = ZenohFrontend(lab.server.hub, lab.session, "lab",
                                  publish={"adc": {"freq_acquisition": 1000}}).start()  # fmt: skip
        restarted = lab.server.hub.clock()
        new: list[Any] = []

        def read_new() -> bool:
            t = zh.read("adc").hub_t
            new.extend(t[t > restarted])
            return len(new) >= 100

        wait_for(read_new, "100 samples of the new hub")
        assert zh.duplicates.get("adc", 0) < 10  # at most the history overlapping what we read


def test_without_a_name_the_one_hub_up_is_taken(lab: Lab) -> None:
    with ZenohHub.connect(zenoh=lab.endpoint) as zh:
        assert zh.name == "lab"
    other = ZenohFrontend(lab.server.hub, lab.session, "other").start()
    try:
        with pytest.raises(InvalidArgument, match="give the hub's name: lab, other are up"):
            ZenohHub.connect(zenoh=lab.endpoint)
    finally:
        other.close()
    lab.front.close()
    wait_for(lambda: not alive_names(lab.endpoint), "no hub up")
    with pytest.raises(TransportError, match="no hub is up on Zenoh at tcp/127.0.0.1:"):
        ZenohHub.connect(zenoh=lab.endpoint)


def alive_names(endpoint: str) -> list[tuple[str, str]]:
    session = open_session(endpoint, "client")
    try:
        return alive(session, 1.0)
    finally:
        close_session(session)
