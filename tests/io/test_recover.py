"""``robocli recover``: a recording killed with SIGKILL (or cut anywhere) rewritten into a
file that the ``mcap`` package's own reader opens whole, summary included; and the user's
files are never destroyed."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.exceptions import McapError
from mcap.reader import make_reader

from robocli.io.record import info, recover
from robocli.io.record.mcapfile import truncated_hint
from tests.commands.helpers import one_line_error, run, running
from tests.waiting import wait_for


def _read_whole(path: Path) -> int:
    """The messages of ``path`` through ``make_reader``, which needs the summary and footer."""
    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None, "no summary"
        count = sum(1 for _ in reader.iter_messages())
        assert count == summary.statistics.message_count
        return count


def _make_reader_fails(path: Path) -> bool:
    try:
        _read_whole(path)
    except (McapError, AssertionError, ValueError, EOFError):
        return True
    return False


def _messages(path: Path) -> int:
    try:
        return info(path).messages
    except Exception:
        return 0


def _kill_mid_recording(path: Path, at_least: int = 40) -> None:
    """``robocli record`` of the embedded Pioneer, killed with SIGKILL once ``at_least``
    messages are on disk (an event: the file read back, not a time)."""
    with running("record", "--pioneer", "sim", "-o", str(path)) as proc:
        assert proc.stderr is not None
        assert "recording to" in proc.stderr.readline()
        wait_for(lambda: _messages(path) >= at_least, what="messages on disk")
        proc.kill()
        proc.wait(30)


def _kill_and_recover(tmp_path: Path, n: int) -> tuple[int, int]:
    """One kill -9 then recover: (messages robocli reads in the killed file, in the
    recovered one through make_reader)."""
    path = tmp_path / f"killed{n}.mcap"
    _kill_mid_recording(path)
    assert _make_reader_fails(path)  # what the viewers met
    scanned = info(path)
    assert not scanned.summary
    proc = run("recover", str(path))
    assert proc.returncode == 0, proc.stderr
    out = tmp_path / f"killed{n}.recovered.mcap"
    assert f"into {out}" in proc.stderr and "Traceback" not in proc.stderr
    return scanned.messages, _read_whole(out)


def test_a_killed_recording_recovers_whole(tmp_path: Path) -> None:
    scanned, recovered = _kill_and_recover(tmp_path, 0)
    assert recovered == scanned >= 40
    # every reader points to recover: info in its summary, the others in a note
    path = tmp_path / "killed0.mcap"
    text = run("info", str(path))
    assert text.returncode == 0 and f"robocli recover {path}" in text.stdout
    out = run("export", str(path), "-f", "jsonl", "-o", str(tmp_path / "csv"))
    assert out.returncode == 0 and f"robocli: note: {truncated_hint(path)}" in out.stderr
    dump = run("dump", "pioneer", "--file", str(path), "-n", "3")
    assert dump.returncode == 0 and "robocli recover" in dump.stderr
    # the recovered file: channels, schemas and messages as robocli read them in the cut one
    whole = info(tmp_path / "killed0.recovered.mcap")
    assert whole.summary and not whole.truncated
    cut = info(path)
    assert [(c.topic, c.schema, c.count, c.metadata) for c in whole.channels] == [
        (c.topic, c.schema, c.count, c.metadata) for c in cut.channels
    ]


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_a_batch_of_killed_recordings_all_recover(tmp_path: Path) -> None:
    """The issue's Done-when: every ``kill -9`` file of a 20-run batch recovers whole."""
    results = [_kill_and_recover(tmp_path, n) for n in range(20)]
    assert all(scanned == recovered >= 40 for scanned, recovered in results), results


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> bytes:
    """A whole recording of the embedded Pioneer with its laser (several chunks)."""
    path = tmp_path_factory.mktemp("finished") / "whole.mcap"
    proc = run("record", "--pioneer", "sim", "-n", "150", "-o", str(path))
    assert proc.returncode == 0, proc.stderr
    return path.read_bytes()


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_a_cut_anywhere_recovers_to_a_valid_file(finished: bytes, data: st.DataObject,
                                                 tmp_path_factory: pytest.TempPathFactory
                                                 ) -> None:  # fmt: skip
    """A finished file cut at any offset past its header recovers into a file make_reader
    reads whole, with every message robocli reads in the cut file."""
    folder = tmp_path_factory.mktemp("cut")
    cut = data.draw(st.integers(100, len(finished) - 1))
    path = folder / "cut.mcap"
    path.write_bytes(finished[:cut])
    stats = recover(path, folder / "out.mcap")
    assert stats.truncated
    assert _read_whole(folder / "out.mcap") == stats.messages == info(path).messages


def test_recover_never_destroys_a_file(tmp_path: Path) -> None:
    path = tmp_path / "killed.mcap"
    _kill_mid_recording(path, at_least=5)
    before = path.read_bytes()
    # the output is the input: by its name, another spelling, a hard link
    (tmp_path / "sub").mkdir()
    for same in (str(path), f"{tmp_path}/sub/../killed.mcap"):
        assert "being recovered" in one_line_error(run("recover", str(path), "-o", same,
                                                       "--overwrite"), 2)  # fmt: skip
    os.link(path, tmp_path / "hard.mcap")
    one_line_error(run("recover", str(path), "-o", str(tmp_path / "hard.mcap"),
                       "--overwrite"), 2)  # fmt: skip
    # an existing output is refused without --overwrite, replaced with it
    precious = tmp_path / "precious.mcap"
    precious.write_bytes(b"precious")
    line = one_line_error(run("recover", str(path), "-o", str(precious)), 2)
    assert "exists" in line and "--overwrite" in line
    assert precious.read_bytes() == b"precious"
    assert run("recover", str(path), "-o", str(precious), "--overwrite").returncode == 0
    assert _read_whole(precious) > 0
    # a symbolic link is never written through, with or without --overwrite
    target = tmp_path / "target.txt"
    target.write_bytes(b"target")
    link = tmp_path / "link.mcap"
    link.symlink_to(target)
    for extra in ([], ["--overwrite"]):
        assert "symbolic link" in one_line_error(run("recover", str(path), "-o", str(link),
                                                     *extra), 2)  # fmt: skip
    assert target.read_bytes() == b"target" and link.is_symlink()
    # a second recover to the default name is refused: the first one's file stays
    assert run("recover", str(path)).returncode == 0
    first = (tmp_path / "killed.recovered.mcap").read_bytes()
    assert "exists" in one_line_error(run("recover", str(path)), 2)
    assert (tmp_path / "killed.recovered.mcap").read_bytes() == first
    assert "cannot write" in one_line_error(run("recover", str(path), "-o",
                                                str(tmp_path / "no" / "x.mcap")), 2)  # fmt: skip
    assert path.read_bytes() == before  # the input is never written
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".part")]


def test_recover_of_what_is_not_a_recording(tmp_path: Path) -> None:
    notes = tmp_path / "notes.mcap"
    notes.write_text("hello")
    assert "not an MCAP file" in one_line_error(run("recover", str(notes)), 2)
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    assert "truncated before its first record" in one_line_error(run("recover", str(empty)), 2)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty.mcap", "notes.mcap"]
