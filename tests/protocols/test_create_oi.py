"""iRobot Create 2 Open Interface (pure Python): commands, sensor packets and groups, the
stream's frames and the command framer, against the golden vectors of
``specs/create_oi.jsonl`` (the specification's examples) byte for byte."""

from __future__ import annotations

import json
from typing import Any

import pytest

from robocli.errors import ChecksumError, FramingError, InvalidArgument, ProtocolError
from robocli.protocols import create_oi as oi
from tests.paths import SPECS

SPEC = SPECS / "create_oi.jsonl"


def _vectors() -> list[dict[str, Any]]:
    head, *vectors = (json.loads(line) for line in SPEC.read_text().splitlines() if line)
    assert head["count"] == len(vectors) > 0  # the file cannot pass vacuously
    return vectors


VECTORS = _vectors()
COMMANDS = [v for v in VECTORS if v["kind"] == "command"]
SENSORS = [v for v in VECTORS if v["kind"] == "sensor"]
STREAMS = [v for v in VECTORS if v["kind"] == "stream"]


def _fields(v: dict[str, Any]) -> dict[str, Any]:
    f = dict(v["fields"])
    if "digits" in f:
        f["digits"] = bytes.fromhex(f["digits"])
    return f


def test_every_kind_has_vectors() -> None:
    assert COMMANDS and SENSORS and STREAMS
    assert len(COMMANDS) + len(SENSORS) + len(STREAMS) == len(VECTORS)


@pytest.mark.parametrize("v", COMMANDS, ids=[v["name"] for v in COMMANDS])
def test_command_vector(v: dict[str, Any]) -> None:
    data = bytes.fromhex(v["hex"])
    op, fields = oi.parse_command(data)
    assert op == oi.Op[v["op"]] and fields == _fields(v)
    assert oi.build_command(op, **fields) == data
    assert oi.command_length(data) == len(data)
    framer = oi.CommandFramer()
    assert [c for b in data for c in framer.feed(bytes([b]))] == [data]  # byte by byte
    garbage = b"\x00\x01\x7f\xff"
    assert framer.feed(garbage + data + garbage + data) == [data, data]
    assert framer.stats.dropped_bytes == 2 * len(garbage) and framer.pending == 0


@pytest.mark.parametrize("v", SENSORS, ids=[v["name"] for v in SENSORS])
def test_sensor_vector(v: dict[str, Any]) -> None:
    data = bytes.fromhex(v["hex"])
    assert oi.decode_packets(v["ids"], data) == v["fields"]
    assert oi.encode_packets(v["ids"], v["fields"]) == data
    assert sum(oi.packet_size(i) for i in v["ids"]) == len(data)


@pytest.mark.parametrize("v", STREAMS, ids=[v["name"] for v in STREAMS])
def test_stream_vector(v: dict[str, Any]) -> None:
    data = bytes.fromhex(v["hex"])
    want = [(pid, fields) for pid, fields in v["packets"]]
    assert oi.parse_stream(data) == want
    values = {k: val for _, f in want for k, val in f.items()}
    assert oi.build_stream([pid for pid, _ in want], values) == data


def test_packet_sizes_and_groups_as_the_specification() -> None:
    sizes = {0: 26, 1: 10, 2: 6, 3: 10, 4: 14, 5: 12, 6: 52, 100: 80, 101: 28, 106: 12,
             107: 9}  # fmt: skip
    assert {g: oi.packet_size(g) for g in oi.GROUPS} == sizes
    two = {19, 20, 22, 23, 25, 26, *range(27, 32), 33, *range(39, 45), *range(46, 52),
           *range(54, 58)}  # fmt: skip
    assert {p for p in oi.PACKETS if oi.packet_size(p) == 2} == two
    assert set(oi.PACKETS) == set(range(7, 59))
    signed = {19, 20, 23, 24, 39, 40, 41, 42, 43, 44, 54, 55, 56, 57}
    for p in oi.PACKETS:  # -1 survives a signed field only
        name = oi.PACKETS[p][0]
        back = oi.decode_packets([p], oi.encode_packets([p], {name: -1}))[name]
        assert (back == -1) == (p in signed), p


def test_encode_clamps_to_the_field_range() -> None:
    assert oi.encode_packets([19], {"distance": 10**6}) == b"\x7f\xff"
    assert oi.encode_packets([22], {"voltage": -3}) == b"\x00\x00"


@pytest.mark.parametrize(
    ("call", "error"),
    [
        (lambda: oi.parse_command(b""), ProtocolError),
        (lambda: oi.parse_command(b"\x89\x00"), ProtocolError),  # drive cut short
        (lambda: oi.parse_command(b"\x02"), ProtocolError),  # no such opcode
        (lambda: oi.parse_command(b"\x8c\x05\x01\x40\x10"), ProtocolError),  # song 5
        (lambda: oi.parse_command(b"\x8c\x00\x11" + b"\x40\x10" * 17), ProtocolError),
        (lambda: oi.build_command(oi.Op.DRIVE, velocity=40000, radius=0), InvalidArgument),
        (lambda: oi.packet_size(59), ProtocolError),
        (lambda: oi.decode_packets([100], b"\x00" * 79), ProtocolError),
        (lambda: oi.decode_packets([7], b"\x00\x00"), ProtocolError),
        (lambda: oi.parse_stream(b"\x13\x02\x07"), FramingError),
        (lambda: oi.parse_stream(b"\x14\x00\xec"), FramingError),
        (lambda: oi.parse_stream(b"\x13\x02\x07\x00\x00"), ChecksumError),
        (lambda: oi.parse_stream(b"\x13\x03\x3b\x00\x00\xaf"), ProtocolError),  # no 59
        (lambda: oi.build_stream([100, 100, 100, 100], {}), InvalidArgument),
    ],
)
def test_bad_input_raises_typed_errors(call: Any, error: type[Exception]) -> None:
    with pytest.raises(error):
        call()


def test_framer_resynchronises_and_counts_what_it_drops() -> None:
    framer = oi.CommandFramer()
    drive = oi.build_command(oi.Op.DRIVE_DIRECT, right=100, left=100)
    bad_song = b"\x8c\x09"  # song 9 does not exist: the opcode byte and the 9 are dropped
    got = framer.feed(b"\x00\x03" + bad_song + b"\x80" + drive[:3])
    assert got == [b"\x80"] and framer.pending == 3
    assert framer.feed(drive[3:]) == [drive]
    s = framer.stats
    assert (s.frames, s.dropped_bytes, s.bad_lengths) == (2, 4, 1)


def test_framer_is_bounded() -> None:
    """A stream or query list announces at most 255 ids: the framer never holds more than
    one longest command, however much arrives."""
    framer = oi.CommandFramer()
    framer.feed(b"\x95\xff" + b"\x07" * 200)
    assert framer.pending == 202
    assert framer.pending <= oi.MAX_COMMAND
    assert framer.feed(b"\x13" * 100) == [b"\x95\xff" + b"\x07" * 200 + b"\x13" * 55]
    assert framer.pending == 0 and framer.stats.dropped_bytes == 45  # 19 is no opcode
    framer.feed(b"\x95\x02\x07")
    framer.reset()
    assert framer.pending == 0


def test_stream_framer_resynchronises_on_headers_and_checksums() -> None:
    """A client's view: garbage before a frame is dropped; a 19 inside garbage that looks
    like a header is found out by its checksum (counted) once enough bytes came."""
    frame = bytes.fromhex(next(v["hex"] for v in STREAMS))
    framer = oi.StreamFramer()
    assert framer.feed(b"\x00\x13\x13" + frame[:4]) == [] and framer.pending > 0
    assert framer.feed(frame[4:] + frame * 3) == [frame] * 4
    s = framer.stats
    assert (s.frames, s.bad_checksums, s.dropped_bytes, framer.pending) == (4, 2, 3, 0)
    bad = frame[:-1] + bytes([frame[-1] ^ 1])
    assert framer.feed(bad + frame) == [frame]
    assert framer.stats.bad_checksums == 3
    assert [c for b in frame for c in framer.feed(bytes([b]))] == [frame]  # byte by byte
    framer.feed(b"\x13\xff")
    assert framer.pending == 2 <= 258
    framer.reset()
    assert framer.pending == 0
