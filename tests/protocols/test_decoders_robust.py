"""Every public decoder, fed arbitrary bytes, returns or raises a robocli error (nothing else),
and a decoding failure names the packet. ros4mat inflation is bounded (zlib bombs)."""

from __future__ import annotations

import struct
import sys
import tracemalloc
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from robocli.errors import FramingError, ProtocolError
from robocli.protocols import arcos, layout
from robocli.protocols import ros4mat as r4m
from robocli.protocols import simple_message as sm
from robocli.protocols.common import enum_or_int
from tests import reference

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "fuzz"))
import fuzz_decoders

GOLDEN = reference.golden_frames()


# The decoders are driven by the fuzz harnesses themselves (fuzz/fuzz_decoders.py), with every
# option byte, so that what `make fuzz` runs for minutes runs here on Hypothesis's examples.


def sm_decoders(frame: bytes) -> None:
    for option in range(16):  # byte order x real size x length repaired x validated
        fuzz_decoders.fuzz_simple_message(bytes((option,)) + frame)


def r4m_decoders(frame: bytes) -> None:
    for option in range(4):  # sizes repaired, inflate tried
        fuzz_decoders.fuzz_ros4mat(bytes((option,)) + frame)


def mutate(draw: st.DrawFn, frame: bytes) -> bytes:
    data = bytearray(frame)
    for _ in range(draw(st.integers(0, 4))):
        op = draw(st.sampled_from(["flip", "cut", "insert"]))
        at = draw(st.integers(0, len(data)))
        if op == "flip" and at < len(data):
            data[at] = draw(st.integers(0, 255))
        elif op == "cut":
            del data[at : at + draw(st.integers(1, 8))]
        else:
            data[at:at] = draw(st.binary(min_size=1, max_size=8))
    return bytes(data)


@st.composite
def golden_mutants(draw: st.DrawFn, kinds: tuple[str, ...]) -> bytes:
    frames = [f for k, _, f in GOLDEN if k in kinds]
    return mutate(draw, draw(st.sampled_from(frames)))


@st.composite
def sm_frames(draw: st.DrawFn) -> bytes:
    """A frame whose length prefix fits, so decoding reaches the body declarations."""
    byteorder = draw(st.sampled_from(["<", ">"]))
    msg_type = draw(st.sampled_from([int(t) for t in sm.SimpleMessageType] + [0, 3, 99]))
    body = draw(st.binary(max_size=600))
    header = struct.pack(byteorder + "iii", msg_type, draw(st.integers(0, 4)), 0)
    return struct.pack(byteorder + "i", len(header) + len(body)) + header + body


@st.composite
def r4m_frames(draw: st.DrawFn) -> bytes:
    """A frame whose header announces its body length, compressed or not."""
    body = draw(st.binary(max_size=400))
    compress = draw(st.booleans())
    wire = zlib.compress(body) if compress and draw(st.booleans()) else body
    header = r4m.Header.build(
        {
            "type": draw(st.sampled_from([int(t) for t in r4m.MsgType] + [0x2F, -1])),
            "error": 0,
            "client_id": 1,
            "size": draw(st.integers(1, 20)),
            "uncompress_size": draw(st.sampled_from([len(body), len(wire), len(body) + 1])),
            "compress_size": len(wire),
            "compression_type": int(compress),
            "packet_timestamp": 0.0,
        }
    )
    return bytes(header) + wire


@settings(max_examples=400, suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(max_size=300) | golden_mutants(("arcos",)))
def test_arcos_decoders_raise_only_robocli_errors(payload: bytes) -> None:
    fuzz_decoders.fuzz_arcos(payload)
    fuzz_decoders.fuzz_arcos(payload[3:-2])  # as a frame's payload


@settings(max_examples=300, suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(max_size=300) | golden_mutants(("sm-le", "sm-be")) | sm_frames())
def test_simple_message_decoder_raises_only_robocli_errors(frame: bytes) -> None:
    sm_decoders(frame)


@settings(max_examples=300, suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(max_size=300) | golden_mutants(("ros4mat",)) | r4m_frames())
def test_ros4mat_decoder_raises_only_robocli_errors(frame: bytes) -> None:
    r4m_decoders(frame)


def test_failures_name_the_packet() -> None:
    with pytest.raises(ProtocolError, match="ARCOS SIP"):
        arcos.decode_sip(b"\x01\x02")
    with pytest.raises(ProtocolError, match="ARCOS CONFIG"):
        arcos.parse_config(b"robot\x00")
    with pytest.raises(ProtocolError, match="ARCOS SYNC2 reply"):
        arcos.parse_sync_reply(b"no terminator")
    with pytest.raises(ProtocolError, match="ARCOS ENCODER"):
        arcos.parse_encoder(b"\x00" * 7)
    with pytest.raises(ProtocolError, match="ARCOS command SAY"):
        arcos.decode_command(b"\x0f\x2b\x05ab")  # a string shorter than its length byte
    with pytest.raises(ProtocolError, match="ARCOS IO") as info:
        arcos.decode_server(b"\xf0\x05\x01")
    assert info.value.__cause__ is not None  # the foreign error stays as the cause
    name, fields = arcos.describe(b"\x20robot\x00", from_client=False)
    assert name == "CONFIG" and "ARCOS CONFIG" in fields["error"]
    with pytest.raises(ProtocolError):
        arcos.describe(b"", from_client=True)
    with pytest.raises(ProtocolError, match="ros4mat ADC"):
        r4m.decode(r4m.encode_packet(r4m.MsgType.ADC, bytes(41), size=1))


def test_one_enum_helper() -> None:
    assert enum_or_int(sm.SimpleMessageType, 10) is sm.SimpleMessageType.JOINT_POSITION
    assert enum_or_int(sm.SimpleMessageType, 12345) == 12345
    assert r4m.decode(r4m.encode_packet(0x2F, b"")).msg_type == 0x2F


def test_layout_views_match_construct() -> None:
    """struct and NumPy views of one declaration read the bytes construct reads."""
    np = pytest.importorskip("numpy")
    raw = bytes(range(40))
    parsed = r4m.Adc.parse(raw)
    view = np.frombuffer(raw, dtype=layout.numpy_dtype(r4m.Adc))[0]
    assert list(view["channels"]) == list(parsed.channels) and view["t"] == parsed.t
    flat = layout.struct_of(r4m.Adc).unpack(raw)
    assert list(flat) == [*parsed.channels, parsed.t]
    assert layout.field_names(arcos.SonarReading) == ("number", "range")
    assert layout.struct_codes(arcos.ENCODER) == "ll"
    with pytest.raises(TypeError):
        layout.struct_of(arcos.CONFIG)  # strings: no fixed layout
    mixed = __import__("construct").Struct("a" / sm.messages(">").Int, "b" / r4m.Adc)
    with pytest.raises(TypeError, match="byte orders"):
        layout.struct_of(mixed)


# ------------------------------------------------------------------------------ zlib bombs


def _zlib_frame(wire: bytes, declared: int) -> bytes:
    header = r4m.Header.build(
        {
            "type": int(r4m.MsgType.ADC),
            "error": 0,
            "client_id": 1,
            "size": 1,
            "uncompress_size": declared,
            "compress_size": len(wire),
            "compression_type": int(r4m.Compression.ZLIB),
            "packet_timestamp": 0.0,
        }
    )
    return bytes(header) + wire


def _peak(fn: Callable[[], Any]) -> int:
    tracemalloc.start()
    try:
        with pytest.raises(ProtocolError) as info:
            fn()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert "inflates past" in str(info.value)
    return peak


@pytest.fixture(scope="module")
def bomb() -> bytes:
    """16 MiB of zeros deflated (about 16 KiB on the wire)."""
    return zlib.compress(bytes(16 * 1024 * 1024), 9)


def test_compressed_bomb_declared_small_is_refused_in_bounded_memory(bomb: bytes) -> None:
    frame = _zlib_frame(bomb, 40)
    assert len(frame) < 64 * 1024
    assert _peak(lambda: r4m.decode(frame)) < 1024 * 1024


def test_bomb_past_a_large_declared_size_is_refused_at_that_size(bomb: bytes) -> None:
    frame = _zlib_frame(bomb, 1024 * 1024)
    assert _peak(lambda: r4m.decode(frame)) < 4 * 1024 * 1024


def test_inflate_refuses_lies_and_broken_streams() -> None:
    body = bytes(range(40))
    good = zlib.compress(body)
    assert r4m.decode(_zlib_frame(good, 40)).body[0]["t"] == struct.unpack("<d", body[32:])[0]
    with pytest.raises(ProtocolError, match="inflated to 40 bytes"):
        r4m.decode(_zlib_frame(good, 41))
    with pytest.raises(ProtocolError, match="truncated"):
        r4m.decode(_zlib_frame(good[:-6], 40))
    with pytest.raises(ProtocolError, match="does not inflate"):
        r4m.decode(_zlib_frame(b"\x00" + good[1:], 40))
    with pytest.raises(ProtocolError, match="declared size"):
        r4m.inflate(good, r4m.MAX_BODY_SIZE + 1)
    with pytest.raises(FramingError):
        r4m.decode(_zlib_frame(good, 40)[:-1])
