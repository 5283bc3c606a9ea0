"""What a damaged or hostile MCAP file does to every command that reads recordings: one line,
exit 2, memory bounded by what the file really holds (never by what it declares)."""

from __future__ import annotations

import json
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.records import Channel, Schema

from robocli.errors import RobocliError
from robocli.io.export import channel_messages
from robocli.io.record import BadRecording, Recorder, info, raw_frames, recover
from robocli.io.record.mcapfile import MAX_CHUNK_BYTES
from tests.commands.helpers import one_line_error, run
from tests.io import mcapbuild as b

GIB = 1 << 30
#: Runs a command in a child that reports its own peak resident memory on its last line.
# The child's own peak: VmHWM belongs to the process image, which exec starts afresh; the
# rusage maximum does not (Linux keeps it across exec, so a fork of a big pytest worker
# reported the worker's 256 MB).
_PEAK = ("import re, sys\nfrom robocli.cli import main\ncode = main(sys.argv[1:])\n"
         "hwm = re.search(r'VmHWM:\\s+(\\d+)', open('/proc/self/status').read()).group(1)\n"
         "print(f'PEAK {hwm}', file=sys.stderr)\n"
         "sys.exit(code)")  # fmt: skip


def _peak_run(*args: str) -> tuple[subprocess.CompletedProcess[str], int]:
    """``robocli ARGS`` in a child: (the process with its PEAK line taken off, peak KiB)."""
    proc = subprocess.run([sys.executable, "-c", _PEAK, *args], capture_output=True, text=True,
                          timeout=300, stdin=subprocess.DEVNULL)  # fmt: skip
    lines = proc.stderr.splitlines()
    assert lines and lines[-1].startswith("PEAK "), proc.stderr
    proc.stderr = "\n".join(lines[:-1]) + "\n"
    return proc, int(lines[-1].split()[1])


def _readers(path: Path, out: Path) -> list[list[str]]:
    """Every command that reads a recording, on ``path``."""
    p = str(path)
    return [
        ["info", p],
        ["export", p, "-f", "jsonl", "-o", str(out)],
        ["plot", p, "-c", "/t", "-f", "v", "-o", str(out / "t.png")],
        ["dump", "pioneer", "--file", p],
        ["validate", p, p],
        ["sim", "pioneer", "--replay", p],
        ["sim", "abb", "--replay", p],
        ["serve", "--replay", p],
    ]


def _bomb(declared: int, zeros: int, content_size: int | None = None) -> bytes:
    """One zstd chunk holding one message of ``zeros`` zero bytes (32 KB per GiB)."""
    head = b.message_head(zeros)
    return b.mcap(*b.schema_and_channel(), b.zstd_chunk(head, zeros, declared, content_size))


@pytest.mark.parametrize("declared, zeros, content_size", [
    (GIB, GIB - 31, None),  # the 33 KB file that cost 2.1 GB
    (1 << 60, 4096, None),  # a MemoryError traceback
    (1 << 60, 4096, 1 << 60),  # the zstd frame claims it too
    (MAX_CHUNK_BYTES, GIB, None),  # declares what it may, inflates to a gigabyte
], ids=["1GiB", "2^60", "2^60-frame", "inflates-past"])  # fmt: skip
def test_a_chunk_declaring_too_much_is_one_line_and_costs_nothing(
        tmp_path: Path, declared: int, zeros: int, content_size: int | None) -> None:  # fmt: skip
    path = tmp_path / "bomb.mcap"
    path.write_bytes(_bomb(declared, zeros, content_size))
    assert path.stat().st_size < 40_000
    out = tmp_path / "out"
    out.mkdir()
    for args in _readers(path, out):
        proc, peak_kib = _peak_run(*args)
        line = one_line_error(proc, 2)
        assert "Chunk record at byte" in line and "bomb.mcap" in line, line
        # the interpreter with numpy and mcap is about 60 MB; a chunk's cap more at most
        assert peak_kib < (150 << 10) + (MAX_CHUNK_BYTES >> 10) * 2, (args, peak_kib)
        if declared > MAX_CHUNK_BYTES:
            assert peak_kib < 200 << 10, (args, peak_kib)  # refused before decompressing
    # recover leaves the chunk out, says so, and writes what the rest holds
    proc, peak_kib = _peak_run("recover", str(path), "-o", str(out / "r.mcap"))
    assert proc.returncode == 0 and "1 malformed records left out" in proc.stderr, proc.stderr
    assert peak_kib < (150 << 10) + (MAX_CHUNK_BYTES >> 10) * 2
    recovered = info(out / "r.mcap")
    assert recovered.summary and recovered.messages == 0
    assert [c.topic for c in recovered.channels] == ["/t"]


def _small_recording(tmp_path: Path, compression: str = "none") -> Path:
    """A recording by robocli's recorder: a raw link and a JSON channel, a few chunks."""
    path = tmp_path / f"small-{compression}.mcap"
    with Recorder(path, compression=compression, chunk_size=1024) as rec:

        def write(i: int) -> None:
            cid = rec.channel("/t", "robocli.pioneer.State")
            rec.write(cid, json.dumps({"v": i, "name": "é"}).encode(), 1_000_000_000 + i)
            raw = rec.channel(
                "/raw",
                None,
                encoding="robocli.raw",
                metadata={"protocol": "arcos", "direction": "rx", "link": "p"},
            )
            rec.write(raw, bytes.fromhex("fafb0332000000"), 1_000_000_000 + i)

        for i in range(40):
            rec.put(write, (i,))
    return path


def _records(data: bytes) -> list[tuple[int, int, int]]:
    """(offset, opcode, length) of the top-level records of a whole file."""
    out, pos = [], 8
    while pos + 9 <= len(data) - 8:
        opcode, length = struct.unpack_from("<BQ", data, pos)
        out.append((pos, opcode, length))
        pos += 9 + length
    return out


def test_malformed_records_are_one_line(tmp_path: Path) -> None:
    """A record whose fields run past its end, text that is not UTF-8, a chunk whose CRC
    fails or whose compression is unknown, a summary pointing outside the file: exit 2,
    naming the record and where it is."""
    good = _small_recording(tmp_path).read_bytes()
    spans = _records(good)
    chunk = next(s for s in spans if s[1] == 0x06)
    cases: dict[str, bytes] = {}
    # the topic's length prefix of the first Channel in the first chunk made huge
    inner = chunk[0] + 9 + 8 + 8 + 8 + 4 + 4 + 8  # times, sizes, crc, "" compression, length
    data = bytearray(good)
    pos = inner
    while data[pos] != 0x04:  # the first Channel record inside the chunk
        pos += 9 + struct.unpack_from("<Q", data, pos + 1)[0]
    crc = chunk[0] + 9 + 24  # the chunk's CRC, 0: not checked
    struct.pack_into("<I", data, pos + 9 + 4, 0xFFFFFFF0)
    struct.pack_into("<I", data, crc, 0)
    cases["a string past the record"] = bytes(data)
    data = bytearray(good)
    data[pos + 9 + 8 : pos + 9 + 10] = b"\xff\xfe"  # the topic's first bytes
    struct.pack_into("<I", data, crc, 0)
    cases["not UTF-8"] = bytes(data)
    data = bytearray(good)
    data[inner + 40] ^= 0xFF  # a byte of the chunk's records: its CRC no longer matches
    cases["CRC"] = bytes(data)
    data = bytearray(good)
    struct.pack_into("<I", data, crc + 4, 3)  # compression "" -> 3 bytes
    cases["compression"] = bytes(data)
    why = {"a string past the record": "runs past the record's end", "not UTF-8": "UTF-8",
           "CRC": "CRC", "compression": "malformed"}  # fmt: skip
    for name, content in cases.items():
        path = tmp_path / f"{name}.mcap"
        path.write_bytes(content)
        line = one_line_error(run("export", str(path), "-f", "jsonl", "-o", str(tmp_path)), 2)
        assert "record at byte" in line and why[name] in line, (name, line)
        with pytest.raises(BadRecording):
            list(channel_messages(path))


@pytest.fixture(scope="module")
def small(tmp_path_factory: pytest.TempPathFactory) -> dict[str, bytes]:
    folder = tmp_path_factory.mktemp("small")
    return {c: _small_recording(folder, c).read_bytes() for c in ("none", "zstd")}


@settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(data=st.data())
def test_any_damage_reads_or_raises_a_robocli_error(tmp_path_factory: pytest.TempPathFactory,
                                                    small: dict[str, bytes],
                                                    data: st.DataObject) -> None:  # fmt: skip
    """Any field of a recording overwritten with anything: every reader returns, or raises
    a robocli error; never another exception (OverflowError, KeyError, MemoryError...)."""
    folder = tmp_path_factory.mktemp("damaged")
    good = bytearray(small[data.draw(st.sampled_from(["none", "zstd"]))])
    for _ in range(data.draw(st.integers(1, 3))):
        at = data.draw(st.integers(8, len(good) - 1))
        value = data.draw(
            st.sampled_from(
                [
                    b"\xff" * 8,
                    struct.pack("<Q", 1 << 63),
                    b"\x80",
                    b"\0\0\0\0",
                    b"\xff\xfe",
                    st.binary(max_size=9),
                ]
            )
        )
        if not isinstance(value, bytes):
            value = data.draw(value)
        good[at : at + len(value)] = value
    cut = data.draw(st.integers(len(good) // 2, len(good)))
    path = folder / "damaged.mcap"
    path.write_bytes(bytes(good[:cut]))
    for reader in (lambda: info(path).as_dict(), lambda: list(channel_messages(path)),
                   lambda: list(raw_frames(path, "arcos")),
                   lambda: recover(path, folder / "r.mcap", overwrite=True)):  # fmt: skip
        try:
            reader()
        except RobocliError:
            pass


def test_channel_records_parse_with_the_package_s_own_classes(tmp_path: Path) -> None:
    """A file built record by record reads as the package writes it: metadata, encodings."""
    path = tmp_path / "built.mcap"
    path.write_bytes(b.mcap(Schema(id=3, name="n", encoding="jsonschema", data=b"{}"),
                            Channel(id=7, schema_id=3, topic="/x", message_encoding="json",
                                    metadata={"k": "v"}),
                            b.plain_chunk(b.message(b'{"v": 1}', channel_id=7))))  # fmt: skip
    summary = info(path)
    assert [(c.topic, c.schema, c.metadata, c.count) for c in summary.channels] == [
        ("/x", "n", {"k": "v"}, 1)
    ]
    assert list(channel_messages(path)) == [("/x", "n", 1, 1, {"v": 1})]


#: Messages a damaged file may hold where a schema promises something else.
HOSTILE = [b"[" * 100_000, b'"str"', b'{"pose": 5}', b'{"pose": {"position": 1}}',
           b'{"robot_time": 1' + b"0" * 400 + b', "position": [1, 2, 3, 4, 5, 6]}',
           b'{"position": [1e400, 1, 2, 3, 4, 5], "name": ["a"]}', b'{"position": 3}',
           b'{"ranges": [1e308, -1e308], "start_angle": 0, "end_angle": 1, '
           b'"pose": {"position": {"x": 1e308, "y": 0}}}',
           b'{"ranges": [1e308, 2], "start_angle": 0, "end_angle": 1}',
           b'{"pose": {"position": {"x": 0, "y": 0}, "orientation": {"w": "x"}}}']  # fmt: skip


@pytest.mark.parametrize("schema, topic", [
    ("foxglove.PoseInFrame", "/arm/tcp"), ("foxglove.LaserScan", "/p/laser"),
    ("robocli.JointState", "/arm/joint_feedback")])  # fmt: skip
def test_messages_that_do_not_fit_their_schema_are_one_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], schema: str,
        topic: str) -> None:  # fmt: skip
    """export, validate's arm log and plot read JSON that is not what the schema says
    (nested past the recursion limit, numbers past a float, objects where numbers go):
    the command ends with one line or draws, never a traceback."""
    from robocli.cli import main

    for i, data in enumerate(HOSTILE):
        path = tmp_path / f"m{i}.mcap"
        path.write_bytes(
            b.mcap(
                Schema(id=1, name=schema, encoding="jsonschema", data=b"{}"),
                Channel(id=1, schema_id=1, topic=topic, message_encoding="json", metadata={}),
                b.plain_chunk(b.message(data, t=1), b.message(data, t=2)),
            )
        )
        for args in (
            ["export", str(path), "-f", "csv", "-o", str(tmp_path / f"o{i}")],
            ["export", str(path), "-f", "irb120-json", "-o", str(tmp_path / f"o{i}")],
            ["plot", str(path), "-c", topic, "-o", str(tmp_path / f"p{i}.png")],
        ):
            code = main(args)
            err = capsys.readouterr().err
            assert code in (0, 1, 2), (data[:40], args, err)
            assert len(err.strip().splitlines()) <= 1, (data[:40], args, err)


def test_times_past_any_calendar_are_shown_as_numbers(tmp_path: Path) -> None:
    """Log times of 2^64 - 1 ns (year 2554) and 2^63: info counts and shows them."""
    path = tmp_path / "far.mcap"
    path.write_bytes(
        b.mcap(
            *b.schema_and_channel(), b.plain_chunk(b.message(t=(1 << 64) - 1), b.message(t=1 << 63))
        )
    )
    for args in (["info", str(path)], ["info", str(path), "--json"]):
        proc = run(*args)
        assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    summary = info(path)
    assert summary.messages == 2 and summary.end_ns == (1 << 64) - 1
