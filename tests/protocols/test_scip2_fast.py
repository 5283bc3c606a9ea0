"""SCIP 2.0 golden vectors (specs/scip2.json, also read by the C suite) through the pure-Python
layer and the C framer/decoder, and hypothesis: the C decode equals the pure-Python reference
for random scans, encodings and cluster counts, and both reject the same corrupt inputs."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robocli.errors import RobocliError
from robocli.protocols import scip2
from robocli.protocols.scip2 import fast
from tests import reference

SPEC = reference.load_spec("scip2")
VECTORS = SPEC["vectors"]


def test_spec_holds_the_briefs_examples() -> None:
    names = {v["name"] for v in VECTORS}
    for g in ("G1", "G2", "G3", "G4", "G5", "G6", "G7", "G8", "G9", "G10", "G11", "G12", "G13"):
        assert any(n.startswith(g + "_") for n in names), g
    assert sum(1 for v in VECTORS if "ranges" in v["fields"]) == 4  # G8, G11, G12, G13


@pytest.mark.parametrize("vector", VECTORS, ids=lambda v: v["name"])
def test_reply_vector(vector: dict[str, Any]) -> None:
    block = bytes.fromhex(vector["hex"])
    fields = vector["fields"]
    reply = scip2.parse_reply(block)
    assert reply.echo.decode() == fields["echo"] and reply.status == fields["status"]
    if "info" in fields:
        assert scip2.parse_info(reply.body) == fields["info"]
        assert (
            scip2.build_reply(reply.echo, reply.status, scip2.build_info(fields["info"])) == block
        )
    elif "ranges" in fields and reply.command != "TM":
        for decode in (scip2.decode_scan, fast.decode_scan):
            scan = decode(block)
            assert scan.timestamp == fields["timestamp"]
            assert scan.ranges.tolist() == fields["ranges"]
            got = None if scan.intensities is None else scan.intensities.tolist()
            assert got == fields.get("intensities")
        rebuilt = scip2.build_scan(
            reply.echo,
            reply.status,
            fields["timestamp"],
            fields["ranges"],
            fields.get("intensities"),
        )
        assert rebuilt == block
    elif "timestamp" in fields:  # TM1
        assert scip2.TimestampLine.parse(reply.body[0] + b"\n") == fields["timestamp"]
    else:
        assert reply.body == () and scip2.build_reply(reply.echo, reply.status) == block
    # the C framer and the pure-Python framer find it whole, fed at once or byte by byte
    for framer in (fast.reply_framer(), scip2.ReplyFramer()):
        assert [b for i in range(len(block)) for b in framer.feed(block[i : i + 1])] == [block]
        assert framer.stats.dropped_bytes == 0


@pytest.mark.parametrize("req", SPEC["requests"], ids=lambda r: r["line"].strip())
def test_request_vector(req: dict[str, Any]) -> None:
    line = req["line"].encode()
    assert scip2.build_request(req["command"], tag=req["tag"], **req["params"]) == line
    parsed = scip2.parse_request(line)
    assert (parsed.command, parsed.params, parsed.tag, parsed.error) == (
        req["command"], req["params"], req["tag"], None,
    )  # fmt: skip


@pytest.mark.parametrize("case", SPEC["checksums"], ids=lambda c: c["text"][:20])
def test_checksum_vector(case: dict[str, str]) -> None:
    assert scip2.sum_char(case["text"].encode()) == case["sum"].encode()


@pytest.mark.parametrize("case", SPEC["encodings"], ids=lambda c: c["chars"])
def test_encoding_vector(case: dict[str, Any]) -> None:
    assert scip2.encode_value(case["value"], case["width"]) == case["chars"].encode()
    assert scip2.decode_value(case["chars"].encode()) == case["value"]


def test_decode_data_direct() -> None:
    lines = scip2.data_lines(scip2.encode_values(range(100), 4))
    assert fast.decode_data(lines, 4, 100).tolist() == list(range(100))
    with pytest.raises(ValueError):
        fast.decode_data(lines, 5, 1)


# ------------------------------------------------------------------ hypothesis


@st.composite
def scans(draw: st.DrawFn) -> tuple[bytes, list[int], list[int] | None]:
    command = draw(st.sampled_from(["GD", "GS", "GE", "MD", "MS", "ME"]))
    start = draw(st.integers(0, 1080))
    end = draw(st.integers(start, min(start + 400, 9999)))
    cluster = draw(st.integers(0, 99))
    count = (end - start + max(cluster, 1)) // max(cluster, 1)
    width = 2 if command[1] == "S" else 3
    top = (1 << (6 * width)) - 1
    values = st.integers(0, top) | st.sampled_from([0, 1, 19, 4095, top])
    ranges = draw(st.lists(values, min_size=count, max_size=count))
    intensities = (
        draw(st.lists(values, min_size=count, max_size=count)) if command[1] == "E" else None
    )
    params: dict[str, int] = {"start": start, "end": end, "cluster": cluster}
    if command[0] == "M":
        params.update(interval=draw(st.integers(0, 9)), count=draw(st.integers(0, 99)))
    tag = draw(st.none() | st.text("abc.@_ 09", max_size=16))
    echo = scip2.build_request(command, tag=tag, **params)[:-1]
    status = "99" if command[0] == "M" else "00"
    block = scip2.build_scan(
        echo, status, draw(st.integers(0, 1 << 24)), ranges, intensities, width
    )
    return block, ranges, intensities


def _outcome(decode: Any, block: bytes, check: bool = True) -> Any:
    try:
        scan = decode(block, check)
    except RobocliError as exc:
        return type(exc)
    ints = None if scan.intensities is None else scan.intensities.tolist()
    return (scan.echo, scan.command, scan.status, scan.timestamp, scan.start, scan.end,
            scan.cluster, scan.remaining, scan.tag, scan.ranges.tolist(), ints)  # fmt: skip


@settings(max_examples=300, deadline=None)
@given(scan=scans())
def test_c_decode_equals_reference(scan: tuple[bytes, list[int], list[int] | None]) -> None:
    block, ranges, intensities = scan
    want = _outcome(scip2.decode_scan, block)
    assert want == _outcome(fast.decode_scan, block)
    assert want[-2] == ranges and want[-1] == intensities
    assert fast.reply_framer().feed(block) == [block]


@pytest.mark.parametrize("tail", [b"\r", b"x", b"\n", b"\r\n"])
def test_both_refuse_bytes_after_the_blocks_end(tail: bytes) -> None:
    """A CR is an end of line only before its LF: ``...\n\n\r`` is a block cut after a
    stray byte, which the C decoder refused and the reference took (make fuzz, decode-scip2)."""
    block = b"GD0384038601\n00P\n00?Xg\n0?X1Dh000d\n\n" + tail
    for check in (True, False):
        want = _outcome(scip2.decode_scan, block, check)
        assert isinstance(want, type) and want == _outcome(fast.decode_scan, block, check)


@settings(max_examples=500, deadline=None)
@given(scan=scans(), data=st.data())
def test_both_reject_the_same_corruption(
    scan: tuple[bytes, list[int], list[int] | None], data: st.DataObject
) -> None:
    block = bytearray(scan[0])
    kind = data.draw(st.sampled_from(["byte", "cut", "line", "many"]))
    if kind == "byte":  # one byte replaced: one fault, so the same error class
        at = data.draw(st.integers(0, len(block) - 1))
        block[at] = data.draw(st.integers(0, 255))
    elif kind == "cut":
        del block[data.draw(st.integers(0, len(block) - 1)) :]
    elif kind == "line":  # a line dropped or doubled
        lines = bytes(block).split(b"\n")
        at = data.draw(st.integers(0, len(lines) - 3))
        lines[at : at + 1] = [] if data.draw(st.booleans()) else [lines[at]] * 2
        block = bytearray(b"\n".join(lines))
    else:
        for _ in range(data.draw(st.integers(2, 6))):
            block[data.draw(st.integers(0, len(block) - 1))] = data.draw(st.integers(0, 255))
    for check in (True, False):
        want = _outcome(scip2.decode_scan, bytes(block), check)
        got = _outcome(fast.decode_scan, bytes(block), check)
        if kind == "many" and isinstance(want, type) and isinstance(got, type):
            continue  # several faults: both reject, each may name a different one first
        assert got == want, (kind, check)


FUZZ_SEQUENCE = """
import random, sys
sys.path[:0] = ["fuzz", "tests"]
import run
one, seeds = run.load("decode-scip2")
rnd = random.Random(1)
for k in range(300):
    s = rnd.choice(seeds)
    cut = rnd.randint(0, len(s))
    junk = bytes(rnd.randrange(256) for _ in range(rnd.randint(0, 64)))
    one(s[:cut] + junk + s[cut:])
print("ok")
"""


def test_decoder_survives_the_fuzz_sequence_that_crashed_it() -> None:
    """The C decoder was once handed a memoryview slice through cffi: a kept decode error's
    traceback cycle, when collected, cleared the memoryview while cffi still held its buffer
    (BufferError, then a segfault at input 21 of this sequence). It now borrows the bytes."""
    root = Path(__file__).resolve().parents[2]
    run = subprocess.run(
        [sys.executable, "-c", FUZZ_SEQUENCE], cwd=root, capture_output=True, text=True, timeout=300
    )
    assert run.returncode == 0 and run.stdout.strip() == "ok", run.stderr[-2000:]
    assert "BufferError" not in run.stderr
