"""Simple Message declarations against the golden vectors and the reference library's traces."""

from __future__ import annotations

import json
import random
import struct
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robocli.errors import FramingError, ProtocolError
from robocli.protocols import simple_message as sm
from tests import reference

ROOT = Path(__file__).resolve().parents[2]
SPEC = reference.load_spec("simple_message")
DATA = ROOT / "tests" / "data" / "simple_message"
# variant -> (byte order, real size, framer)
VARIANTS: dict[str, tuple[sm.ByteOrder, sm.RealSize, str]] = {
    "le": ("<", 4, "sm-le"),
    "bswap": (">", 4, "sm-be"),
    "float64": ("<", 8, "sm-le"),
}


def wire_real(x: float, byteorder: str, real: int) -> float:
    """A nominal real rounded to what the wire can hold."""
    fmt = byteorder + ("f" if real == 4 else "d")
    return float(struct.unpack(fmt, struct.pack(fmt, x))[0])


def assert_fields(actual: Any, nominal: Any, byteorder: str, real: int, path: str = "") -> None:
    if isinstance(nominal, dict):
        assert isinstance(actual, dict), path
        assert set(actual) == set(nominal), (path, set(actual) ^ set(nominal))
        for key, value in nominal.items():
            assert_fields(actual[key], value, byteorder, real, f"{path}.{key}")
    elif isinstance(nominal, list):
        assert isinstance(actual, list) and len(actual) == len(nominal), path
        for i, (a, n) in enumerate(zip(actual, nominal, strict=True)):
            assert_fields(a, n, byteorder, real, f"{path}[{i}]")
    elif isinstance(actual, float):
        assert actual == wire_real(float(nominal), byteorder, real), (path, actual, nominal)
    else:
        assert actual == nominal, (path, actual, nominal)


def load_vectors(variant: str) -> list[dict[str, Any]]:
    vectors: list[dict[str, Any]] = json.loads((DATA / f"vectors_{variant}.json").read_text())
    return vectors


def load_exchange(variant: str) -> list[dict[str, Any]]:
    lines = (DATA / f"exchange_{variant}.jsonl").read_text().splitlines()
    return [json.loads(line) for line in lines if line.strip()]


# ------------------------------------------------------------------------------ (a) specs


def _spec_params(vector: dict[str, Any]) -> tuple[sm.ByteOrder, sm.RealSize]:
    byteorder: sm.ByteOrder = ">" if vector["framer"] == "sm-be" else "<"
    real: sm.RealSize = 8 if vector["variant"] == "float64" else 4
    return byteorder, real


def test_spec_file_shape() -> None:
    assert SPEC["protocol"] == "simple_message"
    for vector in SPEC["vectors"]:
        assert vector["framer"] in ("sm-le", "sm-be")
        assert vector["variant"] in ("le", "bswap", "float64", None)
        assert vector["hex"] == vector["hex"].lower()
        assert vector["message"] in sm.SimpleMessageType.__members__


@pytest.mark.parametrize("vector", SPEC["vectors"], ids=lambda v: v["name"])
def test_spec_vector(vector: dict[str, Any]) -> None:
    byteorder, real = _spec_params(vector)
    frame = bytes.fromhex(vector["hex"])
    fields = vector["fields"]
    msg = sm.decode(frame, byteorder=byteorder, real=real)
    assert sm.SimpleMessageType[vector["message"]] == msg.msg_type
    assert (msg.msg_type, msg.comm_type, msg.reply_code) == (
        fields["msg_type"],
        fields["comm_type"],
        fields["reply_code"],
    )
    if fields["body"] is None:
        assert msg.body is None
    else:
        assert_fields(msg.body, fields["body"], byteorder, real)
    # re-encode the decoded message and the nominal fields: both give the exact bytes
    again = sm.encode(
        msg.msg_type, msg.comm_type, msg.reply_code, msg.body, byteorder=byteorder, real=real
    )
    assert again == frame
    nominal = sm.encode(
        fields["msg_type"],
        fields["comm_type"],
        fields["reply_code"],
        fields["body"],
        byteorder=byteorder,
        real=real,
    )
    assert nominal == frame


def test_rep6_le_is_be_word_swapped() -> None:
    by_name = {v["name"]: bytes.fromhex(v["hex"]) for v in SPEC["vectors"]}
    for stem in ("joint_position", "joint_traj_pt", "status"):
        be, le = by_name[f"rep6_{stem}_be"], by_name[f"rep6_{stem}_le"]
        assert le == b"".join(be[i : i + 4][::-1] for i in range(0, len(be), 4))


# ------------------------------------------------------------------------------ (b) traces


TRACE_VECTORS = [(variant, vector) for variant in VARIANTS for vector in load_vectors(variant)]


@pytest.mark.parametrize(
    ("variant", "vector"), TRACE_VECTORS, ids=[f"{v}-{x['name']}" for v, x in TRACE_VECTORS]
)
def test_library_vector(variant: str, vector: dict[str, Any]) -> None:
    byteorder, real, _ = VARIANTS[variant]
    frame = bytes.fromhex(vector["hex"])
    msg = sm.decode(frame, byteorder=byteorder, real=real)
    assert (msg.msg_type, msg.comm_type, msg.reply_code) == (
        vector["msg_type"],
        vector["comm_type"],
        vector["reply_code"],
    )
    if vector["fields"]:
        assert_fields(msg.body, vector["fields"], byteorder, real)
    else:
        assert msg.body is None
    assert (
        sm.encode(
            msg.msg_type, msg.comm_type, msg.reply_code, msg.body, byteorder=byteorder, real=real
        )
        == frame
    )
    assert (
        sm.encode(
            vector["msg_type"],
            vector["comm_type"],
            vector["reply_code"],
            vector["fields"] or None,
            byteorder=byteorder,
            real=real,
        )
        == frame
    )


def test_quirk_invalid_arrays_are_kept() -> None:
    (vector,) = [v for v in load_vectors("le") if "quirk" in v["name"]]
    msg = sm.decode(bytes.fromhex(vector["hex"]))
    assert isinstance(msg.body, dict)
    assert msg.body["valid_fields"] == sm.ValidFields.TIME | sm.ValidFields.POSITION
    assert any(msg.body["velocities"]) and any(msg.body["accelerations"])


def test_bswap_is_le_word_swapped() -> None:
    for le, be in zip(load_vectors("le"), load_vectors("bswap"), strict=True):
        a, b = bytes.fromhex(le["hex"]), bytes.fromhex(be["hex"])
        assert b == b"".join(a[i : i + 4][::-1] for i in range(0, len(a), 4))


# ------------------------------------------------------------------------------ (c) exchanges


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_exchange_frames_decode(variant: str) -> None:
    byteorder, real, _ = VARIANTS[variant]
    lines = load_exchange(variant)
    assert len(lines) == 17
    decoded = [sm.decode(bytes.fromhex(x["hex"]), byteorder=byteorder, real=real) for x in lines]
    for line, msg in zip(lines, decoded, strict=True):
        frame = bytes.fromhex(line["hex"])
        assert (
            sm.encode(
                msg.msg_type,
                msg.comm_type,
                msg.reply_code,
                msg.body,
                byteorder=byteorder,
                real=real,
            )
            == frame
        )
        if msg.msg_type == sm.SimpleMessageType.JOINT_TRAJ_PT and msg.body is not None:
            assert isinstance(msg.body, dict) and set(msg.body) == {
                "sequence",
                "joints",
                "velocity",
                "duration",
            }
    # the conversation as the README describes it
    assert decoded[0].msg_type == sm.SimpleMessageType.PING and decoded[0].body is None
    assert decoded[1].reply_code == sm.ReplyCode.SUCCESS
    seqs = [
        m.body["sequence"]
        for m in decoded
        if m.comm_type == sm.CommType.SERVICE_REQUEST
        and m.msg_type == sm.SimpleMessageType.JOINT_TRAJ_PT
        and isinstance(m.body, dict)
    ]
    assert seqs == [0, 1, 2, 3, sm.SpecialSeq.STOP_TRAJECTORY]
    failures = [m for m in decoded if m.reply_code == sm.ReplyCode.FAILURE]
    assert {m.msg_type for m in failures} == {
        sm.SimpleMessageType.JOINT_TRAJ_PT,
        sm.SimpleMessageType.STATUS,
    }


# ------------------------------------------------------------------------------ (d) checks


def load_checks(variant: str) -> list[dict[str, Any]]:
    checks: list[dict[str, Any]] = json.loads((DATA / f"library_checks_{variant}.json").read_text())
    return checks


CHECKS = [(variant, c) for variant in VARIANTS for c in load_checks(variant)]


def _checks(prefix: str) -> list[Any]:
    """The library checks whose name starts with ``prefix``, as parameters named
    ``variant-name``."""
    return [pytest.param(v, c, id=f"{v}-{c['name']}") for v, c in CHECKS
            if c["name"].startswith(prefix)]  # fmt: skip


@pytest.mark.parametrize(("variant", "check"), _checks("rx_"))
def test_library_receive_checks(variant: str, check: dict[str, Any]) -> None:
    byteorder, real, _ = VARIANTS[variant]
    frame = bytes.fromhex(check["hex"])
    if not check["library_receive_ok"]:
        with pytest.raises((ProtocolError, FramingError)):
            sm.decode(frame, byteorder=byteorder, real=real)
        if len(frame) >= 16:
            length, msg_type, comm_type, reply_code = struct.unpack(byteorder + "4i", frame[:16])
            if length >= sm.MIN_LENGTH:
                with pytest.raises(ProtocolError):
                    sm.validate_header(msg_type, comm_type, reply_code)
        return
    msg = sm.decode(frame, byteorder=byteorder, real=real)
    received = check["received"]
    assert (msg.msg_type, msg.comm_type, msg.reply_code) == (
        received["msg_type"],
        received["comm_type"],
        received["reply_code"],
    )
    sm.validate_header(msg.msg_type, msg.comm_type, msg.reply_code)
    body_len = 0 if msg.body is None else len(frame) - 16
    assert body_len == received["data_len"]
    standard = sm.messages(byteorder, real).bodies.get(msg.msg_type)
    if check.get("typed_init_ok") and standard is not None and body_len == standard.sizeof():
        if check.get("typed_decoded") is not None:
            assert_fields(msg.body, check["typed_decoded"], byteorder, real)
        else:
            assert isinstance(msg.body, dict)
    elif body_len:
        # Non-standard sizes are never guessed at (the library decodes them from the end).
        if standard is not None and body_len != standard.sizeof():
            assert isinstance(msg.body, bytes)


@pytest.mark.parametrize(("variant", "check"), _checks("tx_"))
def test_library_send_checks(variant: str, check: dict[str, Any]) -> None:
    byteorder, real, _ = VARIANTS[variant]
    header = (check["msg_type"], check["comm_type"], check["reply_code"])
    if not check["library_init_ok"]:
        with pytest.raises(ProtocolError):
            sm.validate_header(*header)
        with pytest.raises(ProtocolError):
            sm.encode(*header, byteorder=byteorder, real=real)
        return
    sm.validate_header(*header)
    if "hex" in check:
        frame = bytes.fromhex(check["hex"])
        body = frame[16:] or None
        assert sm.encode(*header, body, byteorder=byteorder, real=real) == frame


# ------------------------------------------------------------------------------ unit checks


def test_validate_header_messages() -> None:
    with pytest.raises(ProtocolError, match="msg_type is 0"):
        sm.validate_header(0, 1, 0)
    with pytest.raises(ProtocolError, match="comm_type is 0"):
        sm.validate_header(11, 0, 0)
    with pytest.raises(ProtocolError, match="SERVICE_REPLY with reply_code 0"):
        sm.validate_header(11, 3, 0)
    with pytest.raises(ProtocolError, match="reply_code 1 on comm_type 1"):
        sm.validate_header(11, 1, 1)
    for ok in ((11, 3, 3), (11, 3, -1), (11, 4, 0), (65000, 1, 0), (-5, 1, 0)):
        sm.validate_header(*ok)


def test_short_arrays_are_padded_and_long_ones_refused() -> None:
    frame = sm.encode(
        sm.SimpleMessageType.JOINT_POSITION,
        sm.CommType.TOPIC,
        0,
        {"sequence": 0, "joints": [0.5, -0.5]},
    )
    assert len(frame) == 60
    msg = sm.decode(frame)
    assert isinstance(msg.body, dict)
    assert msg.body["joints"] == [0.5, -0.5] + [0.0] * 8
    with pytest.raises(ProtocolError):
        sm.encode(
            sm.SimpleMessageType.JOINT_POSITION,
            sm.CommType.TOPIC,
            0,
            {"sequence": 0, "joints": [0.0] * 11},
        )


def test_ping_rep6_body_and_header_only() -> None:
    rep = sm.encode(sm.SimpleMessageType.PING, sm.CommType.SERVICE_REQUEST, 0, {"data": []})
    assert len(rep) == 56
    assert sm.decode(rep).body == {"data": [0] * 10}
    assert sm.decode(sm.encode(1, 2)).body is None


def test_get_version_and_motoman() -> None:
    frame = sm.encode(
        sm.SimpleMessageType.GET_VERSION,
        sm.CommType.SERVICE_REPLY,
        sm.ReplyCode.SUCCESS,
        {"major": 1, "minor": 2, "patch": 3},
    )
    assert len(frame) == 28
    assert sm.decode(frame).body == {"major": 1, "minor": 2, "patch": 3}
    ctrl = {"robot_id": 0, "sequence": 7, "command": sm.MotomanCommand.START_TRAJ_MODE, "data": []}
    frame = sm.encode(
        sm.SimpleMessageType.MOTOMAN_MOTION_CTRL, sm.CommType.SERVICE_REQUEST, 0, ctrl
    )
    assert len(frame) == 16 + 52
    reply = {
        "robot_id": 0,
        "sequence": 7,
        "command": 200121,
        "result": sm.MotomanResult.BUSY,
        "subcode": 0,
        "data": [1.0],
    }
    frame = sm.encode(
        sm.SimpleMessageType.MOTOMAN_MOTION_REPLY, sm.CommType.SERVICE_REPLY, 1, reply
    )
    assert len(frame) == 16 + 60
    body = sm.decode(frame).body
    assert isinstance(body, dict) and body["result"] == 1 and body["data"][0] == 1.0


def test_unknown_type_and_odd_sizes_stay_raw() -> None:
    frame = sm.encode(65000, sm.CommType.TOPIC, 0, b"\x01\x02\x03")
    msg = sm.decode(frame)
    assert msg.msg_type == 65000 and msg.body == b"\x01\x02\x03"
    with pytest.raises(ProtocolError):
        sm.encode(65000, sm.CommType.TOPIC, 0, {"x": 1})
    # a REP-I0006-ordered JOINT_TRAJ (size first) must not crash the decoder
    rep_body = struct.pack("<i", 2) + bytes(2 * 52)
    sm.decode(sm.encode(sm.SimpleMessageType.JOINT_TRAJ, sm.CommType.TOPIC, 0, rep_body))


def test_framing_errors() -> None:
    good = sm.encode(1, 2)
    with pytest.raises(FramingError):
        sm.decode(good[:-1])
    with pytest.raises(FramingError):
        sm.decode(good + b"\x00")
    with pytest.raises(FramingError):
        sm.decode(bytes.fromhex("080000000100000002000000"))
    big = struct.pack("<4i", 2000, 1, 1, 0) + bytes(1988)
    with pytest.raises(FramingError):
        sm.decode(big)
    assert sm.decode(big, max_length=4096).body == bytes(1988)


def test_frame_size_limit() -> None:
    point = {"sequence": 0, "joints": [], "velocity": 0.0, "duration": 0.0}
    ok = sm.encode(sm.SimpleMessageType.JOINT_TRAJ, 1, 0, {"points": [point] * 19})
    assert len(ok) <= sm.MAX_FRAME_SIZE
    with pytest.raises(ProtocolError, match="exceeds"):
        sm.encode(sm.SimpleMessageType.JOINT_TRAJ, 1, 0, {"points": [point] * 20})


def test_spec_cache_and_sizes() -> None:
    assert sm.messages() is sm.messages("<", 4)
    for (bo, real), point in (((">", 4), 52), (("<", 8), 100), ((">", 8), 100)):
        spec = sm.messages(bo, real)  # type: ignore[arg-type]
        assert spec.JointTrajPt.sizeof() == point
    spec4, spec8 = sm.messages("<", 4), sm.messages("<", 8)
    expected = {
        "JointPosition": (44, 84),
        "Status": (28, 28),
        "JointTrajPtFull": (136, 260),
        "JointFeedback": (132, 256),
        "Header": (12, 12),
        "Prefix": (4, 4),
    }
    for name, (s4, s8) in expected.items():
        assert (getattr(spec4, name).sizeof(), getattr(spec8, name).sizeof()) == (s4, s8)
    assert spec4.JointTrajRep.sizeof() == 4 + 10 * 52
    with pytest.raises(ValueError):
        sm.messages("!", 4)  # type: ignore[arg-type]


ARRAY_KEYS = ("positions", "velocities", "accelerations")
reals = st.floats(allow_nan=False, allow_infinity=False, width=32)


@settings(max_examples=60, deadline=None)
@given(
    byteorder=st.sampled_from(["<", ">"]),
    real=st.sampled_from([4, 8]),
    robot_id=st.integers(-(2**31), 2**31 - 1),
    seq=st.integers(-(2**31), 2**31 - 1),
    valid=st.integers(0, 15),
    t=reals,
    arrays=st.lists(st.lists(reals, max_size=10), min_size=3, max_size=3),
)
def test_traj_pt_full_round_trip(
    byteorder: sm.ByteOrder,
    real: sm.RealSize,
    robot_id: int,
    seq: int,
    valid: int,
    t: float,
    arrays: list[list[float]],
) -> None:
    body = {
        "robot_id": robot_id,
        "sequence": seq,
        "valid_fields": valid,
        "time": t,
        "positions": arrays[0],
        "velocities": arrays[1],
        "accelerations": arrays[2],
    }
    frame = sm.encode(
        sm.SimpleMessageType.JOINT_TRAJ_PT_FULL,
        sm.CommType.SERVICE_REQUEST,
        0,
        body,
        byteorder=byteorder,
        real=real,
    )
    assert len(frame) == 16 + (136 if real == 4 else 260)
    msg = sm.decode(frame, byteorder=byteorder, real=real)
    padded = {
        **body,
        **{k: arrays[i] + [0.0] * (10 - len(arrays[i])) for i, k in enumerate(ARRAY_KEYS)},
    }
    assert msg.body == padded


# ------------------------------------------------------------------------------ (f) C framer


def _core_framer() -> Any:
    core = pytest.importorskip("robocli.core", reason="C core not built")
    return core.Framer


def _stream(variant: str) -> tuple[list[bytes], bytes]:
    frames = [bytes.fromhex(x["hex"]) for x in load_exchange(variant)]
    return frames, b"".join(frames)


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_framer_exchange_stream(variant: str) -> None:
    Framer = _core_framer()
    framer_name = VARIANTS[variant][2]
    frames, stream = _stream(variant)
    framer = Framer(framer_name)
    assert framer.feed(stream) == frames
    assert framer.stats.frames == len(frames)
    assert framer.stats.dropped_bytes == 0 and framer.stats.bad_lengths == 0
    # byte by byte
    framer = Framer(framer_name)
    out: list[bytes] = []
    for i in range(len(stream)):
        out += framer.feed(stream[i : i + 1])
    assert out == frames and framer.pending == 0


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_framer_recovers_after_garbage(variant: str) -> None:
    from tests import reference  # type: ignore[import-not-found]  # the framer model in tests/

    Framer = _core_framer()
    framer_name = VARIANTS[variant][2]
    frames, _ = _stream(variant)
    spec_frames = [bytes.fromhex(v["hex"]) for v in SPEC["vectors"] if v["framer"] == framer_name]
    frames = frames + spec_frames
    rng = random.Random(f"sm-garbage-{variant}")
    tried = 0
    for _ in range(20):
        stream, garbage = reference.with_garbage(frames, rng, (1, 256), 12)
        # Skip the rare draw where garbage happens to form a plausible frame.
        if reference.RefFramer(framer_name, max_frame=sm.MAX_FRAME_SIZE).feed(stream) != frames:
            continue
        tried += 1
        framer = Framer(framer_name, max_frame=sm.MAX_FRAME_SIZE)
        assert reference.fed_in_chunks(framer, stream, 7) == frames
        assert framer.stats.frames == len(frames)
        assert framer.stats.dropped_bytes == garbage
        assert framer.stats.bad_lengths == garbage
    assert tried >= 5
