"""ARCOS spec: golden vectors, every recorded trace frame, the fast SIP path, round trips."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from robocli.core import Framer, arcos_checksum
from robocli.errors import ChecksumError, FramingError
from robocli.io.capture import read_capture
from robocli.protocols import arcos
from robocli.protocols.common import plain
from robocli.robots.pioneer import ROBOT_PARAMS
from tests import reference

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data" / "arcos"
VECTORS = reference.load_spec("arcos")["vectors"]
BY_NAME = {v["name"]: v for v in VECTORS}
TRACES = sorted(DATA.glob("*.jsonl"))


def _lists(obj: object) -> object:
    """``plain`` with tuples as lists too (JSON has no tuples)."""
    obj = plain(obj)
    if isinstance(obj, dict):
        return {k: _lists(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_lists(v) for v in obj]
    return obj


@pytest.mark.parametrize("vec", VECTORS, ids=[v["name"] for v in VECTORS])
def test_golden_vector_decodes_and_rebuilds(vec: dict) -> None:
    raw = bytes.fromhex(vec["hex"])
    payload = arcos.unframe(raw)
    fields = vec["fields"]
    if vec["message"] == "command":
        cmd = arcos.decode_command(payload)
        assert (cmd.command, cmd.arg) == (fields["command"], fields["arg"])
        assert arcos.encode_command(fields["command"], fields["arg"]) == raw
    elif vec["message"] == "sip":
        assert _lists(arcos.decode_sip(payload[1:])) == fields
        assert _lists(arcos.SIP.parse(payload[1:]))["sonar"] == [
            {"number": n, "range": r} for n, r in fields["sonar"]
        ]
        assert arcos.encode_server(payload[0], arcos.SIP.parse(payload[1:])) == raw
    elif vec["message"] in ("config", "sync2_reply", "sim_laser", "sim_laser_plain", "sim_stat"):
        ptype, body = arcos.decode_server(payload)
        assert {k: v for k, v in _lists(body).items() if v is not None} == fields
        assert arcos.encode_server(ptype, fields) == raw
    else:
        assert payload == bytes((fields["type"],))


@pytest.mark.parametrize("vec", VECTORS, ids=[v["name"] for v in VECTORS])
def test_golden_vector_through_c_framer_with_garbage(vec: dict) -> None:
    raw = bytes.fromhex(vec["hex"])
    framer = Framer("arcos")
    garbage = b"\x00\xfa\x13WMS2\r\xfb"
    frames = framer.feed(garbage) + [f for b in raw for f in framer.feed(bytes((b,)))]
    assert frames == [raw]
    assert framer.stats.dropped_bytes == len(garbage)
    assert arcos_checksum(raw[3:-2]) == arcos.checksum(raw[3:-2]) == int.from_bytes(raw[-2:], "big")


@pytest.mark.parametrize("trace", TRACES, ids=[t.stem for t in TRACES])
def test_every_trace_frame_parses(trace: Path) -> None:
    """Each direction of each recorded session: C framer -> construct, nothing dropped."""
    n = 0
    for item in read_capture(trace):
        payload = arcos.unframe(item.frame)
        if item.direction == "tx":
            arcos.decode_command(payload)
        elif payload[0] != arcos.PacketType.SIM_LASER:  # MobileSim laser: not in our spec
            arcos.decode_server(payload)
        n += 1
    assert n > 0


_SIP_LINE = re.compile(r" 0x32 SIP .*")
_FIELD = re.compile(r"(\w+)=(-?(?:0x[0-9a-f]+|\d+))")
# summary key -> what our decoder gives for it; x/y are compared on the 15 bits ARIA uses
# (AMRISim sends -4 as 65532, and the summaries print either form)
_SUMMARY_KEYS = {
    "x": lambda s: s["x"] & 0x7FFF,
    "y": lambda s: s["y"] & 0x7FFF,
    "th": lambda s: s["th"],
    "lvel": lambda s: s["lvel"],
    "rvel": lambda s: s["rvel"],
    "flags": lambda s: s["flags"],
    "sonar_n": lambda s: len(s["sonar"]),
    "min": lambda s: min(r for _, r in s["sonar"]),
    "max": lambda s: max(r for _, r in s["sonar"]),
    "batx10": lambda s: s["battery_x10"],
    "chg": lambda s: s["charge_state"],
    "rotvel": lambda s: s["rotvel"],
    "temp": lambda s: s["temperature"],
}


def _summary_sips(summary: str) -> list[dict[str, int]]:
    """The SIP lines of a recording's decoded summary, as {key: int} for the keys we check."""
    out = []
    for line in _SIP_LINE.findall(summary):
        fields = {k: int(v, 0) for k, v in _FIELD.findall(line) if k in _SUMMARY_KEYS}
        for k in ("x", "y"):
            fields[k] &= 0x7FFF
        out.append(fields)
    return out


@pytest.mark.parametrize("trace", TRACES, ids=[t.stem for t in TRACES])
def test_sip_fields_match_recorded_summaries(trace: Path) -> None:
    """Our decoders agree with the recording's own decoded summary, SIP by SIP."""
    expected = _summary_sips(trace.with_suffix(".txt").read_text())
    got = []
    for item in read_capture(trace):
        payload = arcos.unframe(item.frame)
        if item.direction == "rx" and payload[0] == arcos.PacketType.SIP:
            s = arcos.decode_sip(payload[1:])
            assert _lists(s) == _lists(arcos.SIP.parse(payload[1:])) | {
                "sonar": [[n, r] for n, r in s["sonar"]]
            }
            got.append(s)
    assert len(got) == len(expected)
    for s, want in zip(got, expected, strict=True):
        assert {"x", "y", "th", "flags", "sonar_n"} <= want.keys()
        assert {k: _SUMMARY_KEYS[k](s) for k in want} == want
    if "f_stale" not in trace.name:
        assert len(got) > 10


@given(st.integers(-0xFFFF, 0xFFFF), st.integers(0, 255))
def test_int_argument_round_trip(value: int, command: int) -> None:
    if command in arcos.STRING_COMMANDS or command == arcos.Command.SIM_SET_POSE:
        return
    cmd = arcos.decode_command(arcos.unframe(arcos.encode_command(command, value)))
    assert (cmd.command, cmd.arg) == (command, value)


@given(st.binary(max_size=199))
def test_string_argument_round_trip(text: bytes) -> None:
    raw = arcos.encode_command(arcos.Command.SAY, text)
    assert arcos.decode_command(arcos.unframe(raw)).arg == text
    assert raw[4:6] == bytes((arcos.ARG_STR, len(text)))


@given(st.integers(-128, 127), st.integers(-128, 127))
def test_two_byte_split_is_the_inverse_of_com2bytes(high: int, low: int) -> None:
    raw = arcos.encode_two_bytes(arcos.Command.VEL2, high, low)
    arg = arcos.decode_command(arcos.unframe(raw)).arg
    assert isinstance(arg, int)
    assert arcos.split_two_bytes(arg) == (high, low)


def test_sim_pose_and_describe() -> None:
    payload = arcos.unframe(arcos.encode_sim_pose(1500, -2500, -90))
    assert arcos.decode_command(payload).arg == (1500, -2500, -90)
    name, fields = arcos.describe(bytes.fromhex(BY_NAME["vel_200"]["hex"])[3:-2], from_client=True)
    assert (name, fields) == ("VEL", {"arg": 200})


def test_bad_frames_raise_clear_errors() -> None:
    good = arcos.encode_command(arcos.Command.VEL, 200)
    with pytest.raises(ChecksumError):
        arcos.unframe(good[:-1] + bytes((good[-1] ^ 1,)))
    with pytest.raises(FramingError):
        arcos.unframe(b"\xfa\xfc" + good[2:])
    with pytest.raises(FramingError):
        arcos.unframe(good[:-1])


def test_every_subtype_has_consistent_params() -> None:
    for name, p in ROBOT_PARAMS.items():
        assert p.subtype == name
        assert p.sonar and p.dist_conv > 0 and p.diff_conv > 0
        # 15-bit odometry must not wrap between two SIPs at top speed (ARIA's 0x1000 rule)
        assert p.max_velocity * 1000 * 0.1 / p.dist_conv < 0x1000
