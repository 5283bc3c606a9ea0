"""ros4mat v3 declarations against the bytes the original client sends."""

from __future__ import annotations

import math
import random
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from robocli.errors import FramingError, InvalidArgument, ProtocolError
from robocli.protocols import ros4mat as r4m
from tests import reference

ROOT = Path(__file__).resolve().parents[2]
SPEC = reference.load_spec("ros4mat")


def test_spec_file_shape() -> None:
    assert SPEC["protocol"] == "ros4mat"
    for vector in SPEC["vectors"]:
        assert vector["framer"] == "ros4mat" and vector["message"] in r4m.MsgType.__members__
    for s in SPEC["structs"]:
        assert "framer" not in s


@pytest.mark.parametrize("vector", SPEC["vectors"], ids=lambda v: v["name"])
def test_spec_vector(vector: dict[str, Any]) -> None:
    frame = bytes.fromhex(vector["hex"])
    header, body = vector["fields"]["header"], vector["fields"]["body"]
    if vector.get("raw_body"):  # robocli's serial stream: the bytes themselves, in hex
        body = bytes.fromhex(body)
    assert r4m.plain(r4m.Header.parse(frame)) == header
    assert r4m.plain(r4m.Packet.parse(frame))["body"] == frame[r4m.HEADER_SIZE :]
    msg = r4m.decode(frame)
    assert msg.msg_type == r4m.MsgType[vector["message"]] == header["type"]
    assert (msg.client_id, msg.size, msg.error) == (header["client_id"], header["size"], 0)
    assert msg.body == body
    # the original client's bytes, from our encoder: from the decoded body and the fields
    assert r4m.encode_request(msg.msg_type, msg.body, client_id=msg.client_id) == frame
    assert r4m.encode_request(header["type"], body, client_id=header["client_id"]) == frame


def test_serial_stream_extension_ids_are_new_and_framed() -> None:
    """robocli's serial stream takes ids the original protocol leaves free, each in a class the
    C framer takes (0x0X, 0x1X, 0x2X), and its vectors frame as one frame each."""
    original = {0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x11, 0x13, *range(0x20, 0x2B)}
    stream = {r4m.MsgType.SERIAL_OPEN, r4m.MsgType.SERIAL_WRITE, r4m.MsgType.SERIAL_CLOSE,
              r4m.MsgType.SERIAL_OPEN_ACK, r4m.MsgType.SERIAL_DATA}  # fmt: skip
    assert not stream & original and all(int(k) >> 4 in (0, 1, 2) for k in stream)
    from robocli.core import Framer

    vectors = [v for v in SPEC["vectors"] if v["message"].startswith("SERIAL_")]
    assert {v["message"] for v in vectors} == {k.name for k in stream}
    framer = Framer("ros4mat")
    frames = framer.feed(b"".join(bytes.fromhex(v["hex"]) for v in vectors))
    assert [f.hex() for f in frames] == [v["hex"] for v in vectors]
    open_ = r4m.decode(bytes.fromhex(vectors[0]["hex"])).body
    assert open_ == {"speed": 115200, "byte_size": 8, "parity": "N", "stop_bits": 10,
                     "port": "/dev/ttyUSB0"}  # fmt: skip


@pytest.mark.parametrize("entry", SPEC["structs"], ids=lambda s: s["struct"])
def test_struct_sizes_and_bytes(entry: dict[str, Any]) -> None:
    decl = r4m.DECLARATIONS[entry["struct"]]
    assert decl.sizeof() == entry["size"] == r4m.STRUCT_SIZES[entry["struct"]]
    if "hex" in entry:
        raw = bytes.fromhex(entry["hex"])
        assert len(raw) == entry["size"]
        assert r4m.plain(decl.parse(raw)) == entry["fields"]
        assert decl.build(entry["fields"]) == raw


def test_every_declaration_has_its_size() -> None:
    assert set(r4m.DECLARATIONS) == set(r4m.STRUCT_SIZES)
    for name, decl in r4m.DECLARATIONS.items():
        assert decl.sizeof() == r4m.STRUCT_SIZES[name], name
    assert r4m.Battery.sizeof() == 54


def test_subscribe_helpers() -> None:
    silent = r4m.encode_request(
        r4m.MsgType.SUBSCRIBE, {"sensor": "adc", "silent": 1, "buffer_size": 0}, client_id=7
    )
    (vector,) = [v for v in SPEC["vectors"] if v["name"] == "subscribe_adc_silent"]
    assert silent.hex() == vector["hex"]
    assert r4m.adc_freq_send_default(100) == 35
    assert r4m.adc_freq_send_default(50) == 22
    assert r4m.sensor_type("ordinateur") == r4m.sensor_type("computer") == r4m.MsgType.COMPUTER
    assert r4m.sensor_type("laser") == r4m.sensor_type("hokuyo") == r4m.MsgType.HOKUYO
    with pytest.raises(InvalidArgument, match="unknown sensor 'sonar'; known: adc"):
        r4m.sensor_type("sonar")
    pull = r4m.encode_request("adc", client_id=7)
    (vector,) = [v for v in SPEC["vectors"] if v["name"] == "pull_adc"]
    assert pull.hex() == vector["hex"]
    with pytest.raises(ProtocolError):
        r4m.encode_request(r4m.MsgType.QUIT, {"x": 1})


def test_serial_cmd_round_trip() -> None:
    body = {
        "cmd": {
            "port_length": 12,
            "speed": 115200,
            "parity": 0,
            "stop_bits": 1,
            "send_length": 5,
            "read_length": 5,
            "read_timeout_sec": 1,
            "read_timeout_usec": 0,
            "close_after": 1,
        },
        "port": b"/dev/ttyUSB0",
        "data": b"hello",
    }
    frame = r4m.encode_request(r4m.MsgType.SERIAL_CMD, body, client_id=3)
    assert len(frame) == 27 + 25 + 12 + 5
    assert r4m.decode(frame).body == body
    ans = r4m.SerialAnsReply.build({"ans": {"status": 0, "data_length": 5}, "data": b"hello"})
    msg = r4m.decode(r4m.encode_packet(r4m.MsgType.SERIAL_ANS, ans, client_id=3))
    assert msg.body == {"ans": {"status": r4m.SerialStatus.OK, "data_length": 5}, "data": b"hello"}


# ------------------------------------------------------------------------------ data replies


def _random_records(decl: Any, n: int, rng: random.Random) -> bytes:
    return bytes(rng.randrange(256) for _ in range(n * decl.sizeof()))


@pytest.mark.parametrize(
    "sensor", ["adc", "imu", "gps", "computer", "battery", "camera", "hokuyo", "kinect"]
)
def test_record_dtype_matches_construct(sensor: str) -> None:
    kind = r4m.sensor_type(sensor)
    decl = r4m.RECORDS.get(kind, r4m.INFO_RECORDS.get(kind))
    assert decl is not None
    dtype = r4m.record_dtype(sensor)
    assert dtype.itemsize == decl.sizeof()
    assert r4m.record_dtype(kind) is dtype
    raw = _random_records(decl, 25, random.Random(sensor))
    array = np.frombuffer(raw, dtype=dtype)
    parsed = r4m.plain(decl[25].parse(raw))

    def compare(a: Any, p: Any) -> None:
        if isinstance(p, dict):
            for key, value in p.items():
                compare(a[key], value)
        else:
            np.testing.assert_array_equal(np.asarray(a), np.asarray(p, dtype=np.asarray(a).dtype))

    for i, record in enumerate(parsed):
        compare(array[i], record)


def test_struct_dtype_rejects_variable_fields() -> None:
    with pytest.raises(TypeError):
        r4m.struct_dtype(r4m.SerialCmdRequest)
    with pytest.raises(ProtocolError):
        r4m.record_dtype("connect" if False else r4m.MsgType.SERIAL_ANS)


@pytest.mark.parametrize("compress", [False, True])
def test_fixed_records_round_trip(compress: bool) -> None:
    records = [
        {
            "vtotal": 12.5,
            "current": 1.25,
            "n_cells": 3,
            "vcell": [4.0, 4.25, 4.25] + [0.0] * 5,
            "state": r4m.BatteryState.UNDER_VOLTAGE | r4m.BatteryState.OVER_CURRENT,
            "state_of_charge": 0.5,
            "t": 100.0 + i,
        }
        for i in range(4)
    ]
    frame = r4m.encode_records(
        "battery", records, client_id=9, packet_timestamp=104.5, compress=compress
    )
    msg = r4m.decode(frame)
    assert (msg.msg_type, msg.client_id, msg.size) == (r4m.MsgType.BATTERY, 9, 4)
    assert msg.compression_type == int(compress) and msg.packet_timestamp == 104.5
    assert msg.body == records
    nan = dict(records[0], state_of_charge=math.nan)
    body = r4m.decode(r4m.encode_records("battery", [nan])).body
    assert math.isnan(body[0]["state_of_charge"])
    header = r4m.Header.parse(frame)
    payload = frame[27:]
    if compress:
        payload = zlib.decompress(payload)
    assert header.uncompress_size == len(payload) == 4 * 54
    array = np.frombuffer(payload, dtype=r4m.record_dtype("battery"))
    assert list(array["t"]) == [100.0, 101.0, 102.0, 103.0]


def test_adc_reply_and_pull_frame() -> None:
    records = [{"channels": [0.5 * c for c in range(8)], "t": 1.0 + k / 100} for k in range(10)]
    msg = r4m.decode(r4m.encode_records(r4m.MsgType.ADC, records, client_id=7))
    assert msg.body == records
    empty = r4m.decode(r4m.encode_records(r4m.MsgType.ADC, [], client_id=7))
    assert empty.size == 0 and empty.body is None
    with pytest.raises(ProtocolError):
        r4m.encode_records("camera", [])


def test_camera_kinect_stereo_hokuyo_replies() -> None:
    info = {"width": 2, "height": 1, "channels": 3, "size_data": 6, "compression": 0, "t": 5.0}
    cam = r4m.CameraData.build({"infos": [info, info], "images": [b"abcdef", b"ghijkl"]}, size=2)
    msg = r4m.decode(r4m.encode_packet(r4m.MsgType.WEBCAM, cam, size=2))
    assert msg.body == {"infos": [info, info], "images": [b"abcdef", b"ghijkl"]}

    stereo = r4m.StereoData.build({"infos": [info, info], "images": [b"LLLLLL", b"RRRRRR"]}, size=1)
    msg = r4m.decode(r4m.encode_packet(r4m.MsgType.WEBCAM_STEREO, stereo, size=1))
    assert msg.body["images"] == [b"LLLLLL", b"RRRRRR"]

    depth = dict(info, channels=1, size_data=4)
    kin = r4m.KinectData.build(
        {
            "infos": [{"rgb": info, "depth": depth}],
            "images": [{"rgb": b"rgbrgb", "depth": b"dd" * 2}],
        },
        size=1,
    )
    msg = r4m.decode(r4m.encode_packet(r4m.MsgType.KINECT, kin, size=1, compress=True))
    assert msg.body["images"] == [{"rgb": b"rgbrgb", "depth": b"dddd"}]

    scan = {
        "angle_min": -1.0,
        "angle_max": 1.0,
        "angle_increment": 0.5,
        "time_increment": 0.0,
        "range_min": 0.0,
        "range_max": 4.0,
        "t": 3.0,
        "size_data": 20,
    }
    hok = r4m.HokuyoData.build({"infos": [scan], "ranges": [[1.0, 1.5, 2.0, 2.5, 3.0]]}, size=1)
    msg = r4m.decode(r4m.encode_packet(r4m.MsgType.HOKUYO, hok, size=1))
    assert msg.body == {"infos": [scan], "ranges": [[1.0, 1.5, 2.0, 2.5, 3.0]]}


def test_error_reply_and_bad_frames() -> None:
    frame = r4m.encode_error(r4m.MsgType.SUBSCRIBE_ACK, "nobody is subscribed", client_id=4)
    msg = r4m.decode(frame)
    assert msg.error == 1 and msg.error_text == "nobody is subscribed" and msg.body is None
    good = r4m.encode_records("adc", [{"channels": [0.0] * 8, "t": 0.0}])
    with pytest.raises(FramingError):
        r4m.decode(good[:-1])
    with pytest.raises(FramingError):
        r4m.decode(good[:20])
    bad = bytearray(good)
    bad[6] = 2  # size 2 records, 40 bytes
    with pytest.raises(ProtocolError):
        r4m.decode(bytes(bad))
    with pytest.raises(ProtocolError):
        r4m.encode_packet(r4m.MsgType.ADC, b"x", size=0)


@pytest.mark.parametrize("kind", [0x80, 0x9F, 0xFF, -1])
def test_an_error_reply_names_a_request_type_over_0x7f_by_its_byte(kind: int) -> None:
    """The header's type is a signed char; a server that read it from the wire as 128-255
    must still be able to answer it (the encoder raised construct's untyped error)."""
    msg = r4m.decode(r4m.encode_error(kind, "unknown message id"))
    assert msg.error == 1 and int(msg.msg_type) & 0xFF == kind & 0xFF


# ------------------------------------------------------------------------------ C framer


def _framer_frames() -> list[bytes]:
    frames = [bytes.fromhex(v["hex"]) for v in SPEC["vectors"]]
    frames.append(
        r4m.encode_records(
            "imu",
            [{"acc": [0.0, 0.0, 1.0], "gyro": [0.0] * 3, "mag": [20.0, 0.0, 40.0], "t": 1.0}] * 3,
            client_id=7,
            compress=True,
        )
    )
    frames.append(r4m.encode_error(r4m.MsgType.SUBSCRIBE_ACK, "no such sensor", client_id=7))
    return frames


def test_framer_spec_stream() -> None:
    core = pytest.importorskip("robocli.core", reason="C core not built")
    frames = _framer_frames()
    stream = b"".join(frames)
    framer = core.Framer("ros4mat")
    assert framer.feed(stream) == frames
    assert framer.stats.frames == len(frames) and framer.stats.dropped_bytes == 0
    framer = core.Framer("ros4mat")
    out: list[bytes] = []
    for i in range(0, len(stream), 5):
        out += framer.feed(stream[i : i + 5])
    assert out == frames and framer.pending == 0
    for frame in out:
        r4m.decode(frame)


def test_framer_recovers_after_garbage() -> None:
    core = pytest.importorskip("robocli.core", reason="C core not built")
    frames = _framer_frames()
    rng = random.Random("ros4mat-garbage")
    # bytes 0xB0..0xFF: never a message id, never a valid error/compression byte
    stream, garbage = reference.with_garbage(frames, rng, (0xB0, 0x100), 40)
    framer = core.Framer("ros4mat")
    assert reference.fed_in_chunks(framer, stream, 11) == frames
    assert framer.stats.frames == len(frames)
    assert framer.stats.dropped_bytes == garbage
