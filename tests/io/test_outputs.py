"""A user's file is never destroyed: every command that writes one refuses it when it exists
(without --overwrite) or is a symbolic link, and touches nothing before its arguments are
checked and its sources connected (issue 21, point 8)."""

from __future__ import annotations

import os
import socket
from pathlib import Path

import pytest

from robocli.io.record import Recorder
from robocli.output import OutputError, check_output, create_output, replace_output
from tests.commands.helpers import one_line_error, run

PRECIOUS = b"a recording nobody can make again\n" * 2000


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])  # nobody listens there once closed


@pytest.fixture(scope="module")
def made(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Inputs some commands read: a recording of an arm, a log."""
    tmp = tmp_path_factory.mktemp("inputs")
    rec = run("record", "--arm", "sim", "-n", "50", "-o", str(tmp / "arm.mcap"))
    assert rec.returncode == 0, rec.stderr
    traj = run("traj", "circle", "-n", "20", "-o", str(tmp / "sim.json"))
    assert traj.returncode == 0, traj.stderr
    return {"arm": tmp / "arm.mcap", "sim": tmp / "sim.json"}


#: Each command class that writes a user's file: its arguments with OUT where the file goes
#: (a suffix it accepts) and ADDR where a robot's address goes (None: it reads files only).
WRITERS = {
    "record": (("record", "--pioneer", "ADDR", "-d", "0.5", "-o", "OUT"), ".mcap"),
    "record-hub": (("record", "--hub", "ADDR", "-d", "0.5", "-o", "OUT"), ".mcap"),
    "record-arm": (("record", "--arm", "ADDR", "-n", "20", "-o", "OUT"), ".mcap"),
    "dump": (("dump", "pioneer", "ADDR", "-n", "3", "-o", "OUT"), ".jsonl"),
    "monitor": (("monitor", "arm", "ADDR", "--count", "3", "-o", "OUT"), ".json"),
    "upload-monitor": (
        ("upload", "arm", "ADDR", "--shape", "circle", "--count", "5", "--output", "OUT"),
        ".json",
    ),
    "upload-record": (
        ("upload", "arm", "ADDR", "--shape", "circle", "--count", "5", "--record", "OUT"),
        ".mcap",
    ),
    "traj": (("traj", "circle", "-n", "20", "-o", "OUT"), ".csv"),
    "traj-plot": (("traj", "circle", "-n", "20", "-o", "TMP/x.json", "--plot", "OUT"), ".png"),
    "validate-plot": (("validate", "SIM", "SIM", "--plot", "OUT"), ".png"),
    "plot": (("plot", "ARM", "-c", "/arm/joint_states", "-o", "OUT"), ".png"),
    "export": (("export", "ARM", "-f", "irb120-json", "-o", "TMP"), "/arm.json"),
}
CONNECTING = [name for name, (args, _) in WRITERS.items() if "ADDR" in args]


def _args(name: str, out: Path, made: dict[str, Path], addr: str = "sim") -> list[str]:
    args, _ = WRITERS[name]
    places = {"OUT": str(out), "ADDR": addr, "ARM": str(made["arm"]), "SIM": str(made["sim"]),
              "TMP": str(out.parent)}  # fmt: skip
    return [a.replace("TMP", str(out.parent)) if a.startswith("TMP/") else places.get(a, a)
            for a in args]  # fmt: skip


def _output(name: str, tmp: Path) -> Path:
    suffix = WRITERS[name][1]
    return tmp / suffix[1:] if suffix.startswith("/") else tmp / f"precious{suffix}"


@pytest.mark.parametrize("name", list(WRITERS))
def test_an_existing_output_is_refused_then_replaced_with_overwrite(
    name: str, tmp_path: Path, made: dict[str, Path]
) -> None:
    out = _output(name, tmp_path)
    out.write_bytes(PRECIOUS)
    refused = run(*_args(name, out, made))
    assert "exists: give --overwrite" in one_line_error(refused, 2)
    assert out.read_bytes() == PRECIOUS
    replaced = run(*_args(name, out, made), "--overwrite", timeout=120)
    assert replaced.returncode == 0, replaced.stderr
    assert out.read_bytes() != PRECIOUS and out.stat().st_size > 0
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".part")]  # nothing left over


@pytest.mark.parametrize("name", list(WRITERS))
def test_a_symlink_is_never_written_through(name: str, tmp_path: Path,
                                            made: dict[str, Path]) -> None:  # fmt: skip
    target = tmp_path / "elsewhere" / "precious.bin"
    target.parent.mkdir()
    target.write_bytes(PRECIOUS)
    out = _output(name, tmp_path)
    out.symlink_to(target)
    for extra in ((), ("--overwrite",)):
        proc = run(*_args(name, out, made), *extra)
        assert "symbolic link" in one_line_error(proc, 2)
        assert target.read_bytes() == PRECIOUS and out.is_symlink()


@pytest.mark.parametrize("name", CONNECTING)
@pytest.mark.parametrize(("addr", "code"), [("bad url:x:y", 2), ("unreachable", 3)])
def test_a_source_that_fails_leaves_the_file_as_it_was(
    name: str, addr: str, code: int, tmp_path: Path, made: dict[str, Path]
) -> None:
    out = _output(name, tmp_path)
    out.write_bytes(PRECIOUS)
    if addr == "unreachable":
        addr = f"tcp://127.0.0.1:{_free_port()}" if name in ("record", "dump") \
            else f"127.0.0.1:{_free_port()}" if name == "record-hub" else "127.0.0.1"  # fmt: skip
    args = _args(name, out, made, addr)
    if addr == "127.0.0.1":  # an arm: its ports have options
        port = _free_port()  # and one above it, for the other port (two ports differ)
        args += ["--state-port", str(port), "--motion-port", str(port + 1)]
    proc = run(*args, "--overwrite")
    one_line_error(proc, code)
    assert out.read_bytes() == PRECIOUS
    fresh = tmp_path / f"new{WRITERS[name][1]}"
    run(*_args(name, fresh, made, addr if code == 2 else "bad url:x:y"))
    assert not fresh.exists()  # nothing made for a session that never was


# ------------------------------------------------------------------ the helper itself


def test_a_whole_file_that_fails_keeps_the_old_one(tmp_path: Path) -> None:
    out = tmp_path / "log.json"
    out.write_bytes(PRECIOUS)
    with pytest.raises(ZeroDivisionError), replace_output(out, overwrite=True) as fh:
        fh.write(b"half a file")
        raise ZeroDivisionError
    assert out.read_bytes() == PRECIOUS and os.listdir(tmp_path) == ["log.json"]


def test_a_link_made_after_the_check_is_not_followed(tmp_path: Path) -> None:
    target = tmp_path / "target"
    target.write_bytes(PRECIOUS)
    out = tmp_path / "out.mcap"
    check_output(out)  # free now...
    out.symlink_to(target)  # ...and a link by the time the file is made
    with pytest.raises(OutputError, match="symbolic link"):
        create_output(out)
    with pytest.raises(OutputError, match="exists"), replace_output(tmp_path / "late") as fh:
        fh.write(b"x")
        (tmp_path / "late").write_bytes(PRECIOUS)  # made meanwhile: not replaced
    assert target.read_bytes() == PRECIOUS == (tmp_path / "late").read_bytes()


def test_a_recorder_that_never_began_makes_no_file(tmp_path: Path) -> None:
    out = tmp_path / "never.mcap"
    rec = Recorder(out, deferred=True)
    rec.close()
    assert not out.exists()
    out.write_bytes(PRECIOUS)
    with pytest.raises(OutputError, match="exists"):
        Recorder(out)
    Recorder(out, overwrite=True, deferred=True).close()
    assert out.read_bytes() == PRECIOUS
