"""C framers (robocli.core) against the pure-Python reference, plus known answers."""

from __future__ import annotations

import json
import pathlib
import shutil
import struct
import subprocess

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from robocli.core import PROTOCOLS, Framer, FramerStats, arcos_checksum
from tests import paths, reference

GOLDEN = reference.golden_frames()
#: The ARCOS vectors of specs/arcos.json (the manual's worked examples and recorded frames).
ARCOS = {name: frame for kind, name, frame in GOLDEN if kind == "arcos"}
ROOT = paths.ROOT


# ------------------------------------------------------------------ known answers


@pytest.mark.parametrize("pkt", ARCOS.values(), ids=ARCOS.keys())
def test_worked_arcos_vectors(pkt: bytes) -> None:
    assert arcos_checksum(pkt[3:-2]) == pkt[-2] << 8 | pkt[-1]
    assert reference.arcos_checksum(pkt[3:-2]) == pkt[-2] << 8 | pkt[-1]
    assert reference.arcos_packet(pkt[3], pkt[4:-2]) == pkt
    f = Framer("arcos")
    assert f.feed(pkt) == [pkt]
    assert f.stats == FramerStats(1, 0, 0, 0)
    assert f.pending == 0


def test_checksum_edges() -> None:
    assert arcos_checksum(b"") == 0
    assert arcos_checksum(b"\x12") == 0x12
    assert arcos_checksum(b"\x12\x34\xff") == 0x1234 ^ 0xFF
    assert arcos_checksum(bytearray(b"\xff\xff\x00\x02")) == 1
    assert arcos_checksum(memoryview(b"\x01\x3b\x01\x00")) == 0x023B


def test_arcos_fa_fa_fb_is_found() -> None:
    pkt = ARCOS["open_int1"]
    f = Framer("arcos")
    assert f.feed(b"\xfa" + pkt[:4]) == []  # FA FA FB ...
    assert f.feed(pkt[4:]) == [pkt]
    assert f.stats == FramerStats(1, 1, 0, 0)


def test_arcos_bad_checksum_then_good() -> None:
    pkt = ARCOS["vel_200"]
    bad = pkt[:-1] + bytes([pkt[-1] ^ 0x80])
    f = Framer("arcos")
    assert f.feed(bad + pkt) == [pkt]
    assert f.stats == FramerStats(1, len(bad), 1, 0)


def test_arcos_frame_survives_until_next_call() -> None:
    f = Framer("arcos")
    frames = list(ARCOS.values())
    out = f.feed(b"".join(frames))
    assert out == frames
    assert list(f.frames()) == []


def test_simple_message_both_orders() -> None:
    for proto, little in (("sm-le", True), ("sm-be", False)):
        fr = reference.sm_frame(b"\x01\x02\x03\x04", little=little)
        f = Framer(proto)
        assert f.feed(fr[:5]) == []
        assert f.pending == 5
        assert f.feed(fr[5:] + fr) == [fr, fr]
        assert f.feed(b"\xff" * 6) == []
        assert f.stats == FramerStats(2, 3, 0, 3)
        assert f.pending == 3


def test_simple_message_max_frame() -> None:
    fr = reference.sm_frame(bytes(100))
    assert Framer("sm-le").feed(fr) == [fr]
    f = Framer("sm-le", max_frame=64)
    assert f.feed(fr) == []
    assert f.stats.bad_lengths >= 1


def test_ros4mat_frames() -> None:
    data = reference.r4m_frame(0x20, bytes(range(40)), size=1)
    err = reference.r4m_frame(0x13, b"no such sensor\x00", error=True)
    pull = reference.r4m_frame(0x20)
    f = Framer("ros4mat")
    assert f.feed(data + err + pull) == [data, err, pull]
    assert len(pull) == 27
    bad = bytearray(pull)
    bad[18] = 2
    assert f.feed(bytes(bad)) == []
    assert f.stats == FramerStats(3, 1, 0, 1)


def test_reset_count_and_errors() -> None:
    f = Framer("arcos")
    pkt = ARCOS["open_int1"]
    f.feed(pkt[:5])
    assert f.pending == 5
    f.reset()
    assert f.pending == 0
    assert f.feed(pkt) == [pkt]
    assert f.count(pkt * 100, chunk=7) == 100
    assert f.count(pkt * 10) == 10
    with pytest.raises(ValueError):
        Framer("modbus")
    with pytest.raises(ValueError):
        Framer("sm-le", max_frame=8)
    with pytest.raises(ValueError):
        f.count(pkt, chunk=-1)
    assert set(PROTOCOLS) == {"arcos", "sm-le", "sm-be", "ros4mat", "scip2"}


# ------------------------------------------------------------------ golden vectors (specs/)


@pytest.mark.parametrize(
    ("kind", "frame"), [(k, f) for k, _, f in GOLDEN], ids=[n for _, n, _ in GOLDEN]
)
def test_golden_vector(kind: str, frame: bytes) -> None:
    f = Framer(kind)
    assert f.feed(frame) == [frame]
    assert f.stats.dropped_bytes == 0
    one = Framer(kind)
    got = [fr for i in range(len(frame)) for fr in one.feed(frame[i : i + 1])]
    assert got == [frame]


def test_golden_vectors_are_all_there() -> None:
    """Every framer has vectors, and as many as the spec files declare."""
    specs = reference.load_specs()
    assert len(GOLDEN) == sum(spec["count"] for spec in specs.values()) > 0
    assert {kind for kind, _, _ in GOLDEN} == set(reference.FRAMER_KINDS)


def _write_spec(folder: pathlib.Path, name: str, count: int | None, n: int) -> None:
    vectors = json.loads(reference.SPECS_DIR.joinpath(f"{name}.json").read_text())["vectors"]
    kinds = {v["framer"]: v for v in vectors}  # one vector of each framer the file feeds
    lines = [json.dumps(list(kinds.values())[i % len(kinds)]) for i in range(n)]
    head = f'{{\n  "protocol": "{name}",\n'
    if count is not None:
        head += f'  "count": {count},\n'
    text = head + '  "vectors": [\n    ' + ",\n    ".join(lines) + "\n  ]\n}\n"
    folder.joinpath(f"{name}.json").write_text(text)


def _spec_folder(tmp: pathlib.Path, count: int | None, n: int) -> pathlib.Path:
    for name in reference.SPEC_NAMES:
        _write_spec(tmp, name, 2, 2)
    _write_spec(tmp, "arcos", count, n)
    return tmp


@pytest.mark.parametrize(("count", "n"), [(None, 0), (0, 0), (3, 2), (1, 2), (None, 2)])
def test_python_loader_refuses_empty_or_miscounted_specs(
    tmp_path: pathlib.Path, count: int | None, n: int
) -> None:
    with pytest.raises(reference.SpecError):
        reference.load_specs(tmp_path)  # empty folder
    folder = _spec_folder(tmp_path, count, n)
    with pytest.raises(reference.SpecError):
        reference.golden_frames(folder)


def test_python_loader_accepts_a_well_counted_folder(tmp_path: pathlib.Path) -> None:
    folder = _spec_folder(tmp_path, 2, 2)
    assert len(reference.golden_frames(folder)) == 2 * len(reference.SPEC_NAMES)


@pytest.fixture(scope="module")
def test_core(tmp_path_factory: pytest.TempPathFactory) -> pathlib.Path:
    """csrc/test_core built the way ``make test-c`` builds it (C89, warnings are errors)."""
    gcc = shutil.which("gcc") or shutil.which("cc")
    if gcc is None:
        pytest.skip("no C compiler to build csrc/test_core")
    exe = tmp_path_factory.mktemp("c") / "test_core"
    csrc = ROOT / "csrc"
    # the sources `make test-c` links: the Makefile's CSRC list, then the test itself
    line = next(x for x in (ROOT / "Makefile").read_text().splitlines() if x.startswith("CSRC"))
    sources = [str(ROOT / p) for p in line.split(":=", 1)[1].split()] + [str(csrc / "test_core.c")]
    cmd = [gcc, "-std=c89", "-Wall", "-Wextra", "-pedantic", "-Werror", "-O1"]
    cmd += ["-D_POSIX_C_SOURCE=200112L", f"-I{csrc}", "-o", str(exe), *sources]
    subprocess.run([*cmd, "-lpthread", "-lm"], check=True, timeout=120)
    return exe


def _run_specs(exe: pathlib.Path, folder: pathlib.Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(exe), "--specs-only", str(folder)], capture_output=True, text=True, timeout=60
    )


def test_c_suite_passes_on_the_real_specs(test_core: pathlib.Path) -> None:
    run = _run_specs(test_core, reference.SPECS_DIR)
    assert run.returncode == 0, run.stderr
    assert " 0 failed" in run.stdout


@pytest.mark.parametrize(("count", "n"), [(None, 2), (0, 0), (3, 2), (1, 2)])
def test_c_suite_fails_on_empty_or_miscounted_specs(
    test_core: pathlib.Path, tmp_path: pathlib.Path, count: int | None, n: int
) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    assert _run_specs(test_core, empty).returncode != 0
    assert _run_specs(test_core, tmp_path / "missing").returncode != 0
    folder = _spec_folder(tmp_path, count, n)
    run = _run_specs(test_core, folder)
    assert run.returncode != 0, run.stdout
    assert "FAIL" in run.stderr
    assert _run_specs(test_core, _spec_folder(tmp_path, 2, 2)).returncode == 0


# ------------------------------------------------------------------ differential


@st.composite
def arcos_frames(draw: st.DrawFn) -> bytes:
    data = draw(st.binary(min_size=0, max_size=60))
    return reference.arcos_packet(draw(st.integers(0, 255)), data)


@st.composite
def sm_frames(draw: st.DrawFn, little: bool) -> bytes:
    return reference.sm_frame(draw(st.binary(max_size=80)), little=little)


@st.composite
def r4m_frames(draw: st.DrawFn) -> bytes:
    kind = draw(st.sampled_from(["data", "error", "pull"]))
    if kind == "data":
        body = draw(st.binary(min_size=1, max_size=80))
        return reference.r4m_frame(0x20, body, size=draw(st.integers(1, 9)))
    if kind == "error":
        return reference.r4m_frame(0x13, draw(st.binary(max_size=30)), error=True)
    return reference.r4m_frame(draw(st.integers(-128, 127)))


@st.composite
def scip_frames(draw: st.DrawFn) -> bytes:
    """SCIP 2.0 reply blocks: echo, status (sometimes a wrong sum, or 1 char), body lines,
    sometimes CR LF line ends."""
    printable = st.binary(min_size=1, max_size=70).map(lambda b: bytes(0x20 + c % 95 for c in b))
    echo = draw(printable.filter(lambda b: len(b) <= 66))
    status = draw(st.sampled_from([b"00", b"99", b"0E", b"10"]))
    line = status + bytes([(sum(status) & 0x3F) + 0x30 + draw(st.sampled_from([0, 0, 0, 1]))])
    if draw(st.integers(0, 9)) == 0:
        line = b"0"
    body = draw(st.lists(printable, max_size=4))
    eol = b"\r\n" if draw(st.integers(0, 5)) == 0 else b"\n"
    return eol.join([echo, line, *body, b"", b""])  # ends in the empty line


FRAMES = {
    "scip2": scip_frames(),
    "arcos": arcos_frames(),
    "sm-le": sm_frames(True),
    "sm-be": sm_frames(False),
    "ros4mat": r4m_frames(),
}


@st.composite
def streams(draw: st.DrawFn, proto: str) -> bytes:
    parts = []
    for _ in range(draw(st.integers(0, 8))):
        kind = draw(st.sampled_from(["frame", "frame", "garbage", "flip", "cut"]))
        fr = draw(FRAMES[proto])
        if kind == "frame":
            parts.append(fr)
        elif kind == "garbage":
            parts.append(draw(st.binary(min_size=1, max_size=20)))
        elif kind == "flip":
            b = bytearray(fr)
            bit = draw(st.integers(0, len(b) * 8 - 1))
            b[bit // 8] ^= 1 << (bit % 8)
            parts.append(bytes(b))
        else:
            parts.append(fr[: draw(st.integers(0, len(fr)))])
    return b"".join(parts)


def _chunks(data: bytes, cuts: list[int]) -> list[bytes]:
    points = sorted({c % (len(data) + 1) for c in cuts})
    out, prev = [], 0
    for p in [*points, len(data)]:
        out.append(data[prev:p])
        prev = p
    return out


def _compare(proto: str, data: bytes, cuts: list[int], max_frame: int | None) -> None:
    c = Framer(proto, max_frame)
    r = reference.RefFramer(proto, max_frame)
    for chunk in _chunks(data, cuts):
        assert c.feed(chunk) == r.feed(chunk)
        assert c.stats == r.stats
        assert c.pending == r.pending


def _stream_and_cuts(data: st.DataObject, proto: str, max_cuts: int) -> tuple[bytes, list[int]]:
    """A drawn stream of ``proto`` and up to ``max_cuts`` places to cut it."""
    return data.draw(streams(proto)), data.draw(st.lists(st.integers(0, 10_000), max_size=max_cuts))


@pytest.mark.parametrize("proto", PROTOCOLS)
@settings(max_examples=200, deadline=None)
@given(data=st.data())
def test_matches_reference(proto: str, data: st.DataObject) -> None:
    _compare(proto, *_stream_and_cuts(data, proto, 12), None)


@pytest.mark.parametrize("proto", PROTOCOLS)
@settings(max_examples=100, deadline=None)
@given(data=st.data())
def test_matches_reference_small_max_frame(proto: str, data: st.DataObject) -> None:
    stream, cuts = _stream_and_cuts(data, proto, 6)
    low = {"arcos": 6, "sm-le": 16, "sm-be": 16, "ros4mat": 27, "scip2": 8}[proto]
    _compare(proto, stream, cuts, data.draw(st.integers(low, low + 60)))


@pytest.mark.parametrize("proto", PROTOCOLS)
@settings(max_examples=100, deadline=None)
@given(junk=st.binary(max_size=300), cuts=st.lists(st.integers(0, 400), max_size=8))
def test_random_bytes_match_reference(proto: str, junk: bytes, cuts: list[int]) -> None:
    _compare(proto, junk, cuts, None)


@settings(max_examples=50, deadline=None)
@given(frames=st.lists(arcos_frames(), min_size=1, max_size=30), size=st.integers(1, 50))
def test_arcos_clean_stream_any_chunking(frames: list[bytes], size: int) -> None:
    data = b"".join(frames)
    f = Framer("arcos")
    got = [fr for i in range(0, len(data), size) for fr in f.feed(data[i : i + size])]
    assert got == frames
    assert f.stats == FramerStats(len(frames), 0, 0, 0)
    assert Framer("arcos").count(data, size) == len(frames)


def test_large_ros4mat_body_grows_buffer() -> None:
    body = bytes(range(256)) * 4096  # 1 MiB
    fr = reference.r4m_frame(0x24, body, size=1)
    f = Framer("ros4mat")
    got = [x for i in range(0, len(fr), 65536) for x in f.feed(fr[i : i + 65536])]
    assert got == [fr]
    assert struct.unpack_from("<I", fr, 14)[0] == len(body)


def test_both_suites_fail_when_a_spec_file_is_missing(
    test_core: pathlib.Path, tmp_path: pathlib.Path
) -> None:
    for name in ("arcos", "simple_message"):
        _write_spec(tmp_path, name, 2, 2)
    with pytest.raises(reference.SpecError, match="ros4mat"):
        reference.load_specs(tmp_path)
    run = _run_specs(test_core, tmp_path)
    assert run.returncode != 0 and "no golden vector for framer" in run.stderr
