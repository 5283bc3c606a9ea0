"""Every command, fed each class of bad input, says one line on stderr and ends with the
README's code (2 for usage, 3 not reachable, 1 failure), never a traceback: the classes
are derived from each command's parameters (through the Typer app, so a new command is
fed them too), then the concrete failures of issue 22, each at its cause."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from robocli.cli import main
from tests.commands.helpers import ROBOCLI, one_line_error, run
from tests.commands.test_grammar import COMMANDS


def _one_line(capsys: pytest.CaptureFixture[str], args: list[str], code: int) -> str:
    got = main(args)
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert got == code, (args, got, err)
    assert len(lines) == 1 and lines[0].startswith("robocli: "), (args, err)
    assert "Traceback" not in err
    return lines[0]


def _needed(cmd: Any) -> list[str]:
    """Values for a command's required arguments that pass parsing (what the class under
    test does not touch): a URL positional ``sim``, other arguments a file that exists."""
    out = []
    for p in cmd.params:
        if p.param_type_name == "argument" and p.required:
            out.append("sim" if p.metavar in ("URL", "[URL]") else __file__)
    return out


def _first(cmd: Any, kind: type) -> Any:
    """The first visible option of ``kind`` (not a flag, not a choice), or None."""
    for p in cmd.params:
        td = getattr(p, "type_descriptor", None)
        if p.param_type_name == "option" and not getattr(p, "hidden", False) and td is not None \
                and td.annotation is kind and not td.choices and not p.is_flag:  # fmt: skip
            return p
    return None


@pytest.mark.parametrize("path", sorted(COMMANDS))
def test_an_unknown_option(path: str, capsys: pytest.CaptureFixture[str]) -> None:
    line = _one_line(capsys, [*path.split(), "--no-such-option"], 2)
    assert "--no-such-option" in line


@pytest.mark.parametrize("path", sorted(COMMANDS))
@pytest.mark.parametrize("value", ["x", "nan"])
def test_a_number_that_is_not_one(path: str, value: str,
                                  capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    cmd = COMMANDS[path]
    option = _first(cmd, float if value == "nan" else int) or _first(cmd, float)
    if option is None:
        pytest.skip("no number option")
    _one_line(capsys, [*path.split(), *_needed(cmd), option.opts[0], value], 2)


@pytest.mark.parametrize("path", sorted(COMMANDS))
def test_a_value_outside_a_choice(path: str, capsys: pytest.CaptureFixture[str]) -> None:
    cmd = COMMANDS[path]
    choice = next((p for p in cmd.params if not getattr(p, "hidden", False)
                   and getattr(p, "type_descriptor", None) is not None
                   and p.type_descriptor.choices), None)  # fmt: skip
    if choice is None:
        pytest.skip("no choice")
    args = [*path.split(), *_needed(cmd)]
    if choice.param_type_name == "argument":
        args = [*path.split(), "bogus"]
    else:
        args += [choice.opts[0], "bogus"]
    line = _one_line(capsys, args, 2)
    assert "bogus" in line


@pytest.mark.parametrize("path", sorted(COMMANDS))
def test_a_malformed_device_url(path: str, capsys: pytest.CaptureFixture[str]) -> None:
    cmd = COMMANDS[path]
    first = next((p for p in cmd.params if p.param_type_name == "argument"), None)
    if first is None or first.metavar not in ("URL", "[URL]"):
        pytest.skip("no device URL")
    _one_line(capsys, [*path.split(), "bad url:1:2"], 2)


# ------------------------------------------------------------- the failures issue 22 lists


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("rec") / "run.mcap"
    proc = run("record", "--pioneer", "sim", "-n", "40", "-o", str(path))
    assert proc.returncode == 0, proc.stderr
    return path


@pytest.mark.parametrize(
    ("args", "code", "says"),
    [
        (["info", "/etc/passwd"], 2, "not an MCAP file"),
        (["connect", "laser", "sim", "--start", "900", "--end", "100"], 2, "before --start"),
        (
            [
                "upload",
                "arm",
                "sim",
                "--shape",
                "circle",
                "--motion-port",
                "28000",
                "--state-port",
                "28000",
            ],
            2,
            "both 28000",
        ),
        (
            ["monitor", "arm", "sim", "--motion-port", "28000", "--state-port", "28000"],
            2,
            "both 28000",
        ),
        (["record", "--arm", "127.0.0.1:28002", "-o", "{tmp}/a.mcap"], 2, "--motion-port"),
    ],
)
def test_issue_22_usage_errors(args: list[str], code: int, says: str, tmp_path: Path,
                               capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    line = _one_line(capsys, [a.replace("{tmp}", str(tmp_path)) for a in args], code)
    assert says in line and "SCIP echo" not in line


def test_serve_replay_of_an_empty_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    _one_line(capsys, ["serve", "--replay", str(empty)], 2)


@pytest.mark.parametrize("name", ["/nonexistent/x.png", "x.txt"])
def test_plot_output_errors(name: str, recording: Path, tmp_path: Path,
                            capsys: pytest.CaptureFixture[str]) -> None:  # fmt: skip
    out = name if name.startswith("/") else str(tmp_path / name)
    _one_line(capsys, ["plot", str(recording), "-c", "/pioneer/pose", "-o", out], 2)
    assert not Path(out).exists()


def test_a_zenoh_error_has_no_library_path() -> None:
    pytest.importorskip("zenoh")
    line = one_line_error(run("router", "--listen", "tcp/8.8.8.8:7447"), 3)
    assert ".rs" not in line and "/root/" not in line


@pytest.mark.parametrize("argv", [["export", "{rec}", "-f", "csv", "-o", "{tmp}/o"],
                                  ["validate", "{rec}", "{rec}"]])  # fmt: skip
def test_a_missing_extra_is_one_line_naming_it(argv: list[str], recording: Path,
                                                tmp_path: Path) -> None:  # fmt: skip
    """Without the record extra (an ``mcap`` that cannot be imported comes first on the
    path), the command names the extra in one line, exit 1."""
    blocker = tmp_path / "blocker" / "mcap"
    blocker.mkdir(parents=True)
    (blocker / "__init__.py").write_text(
        "raise ModuleNotFoundError(\"No module named 'mcap'\", name='mcap')\n"
    )
    env = {**os.environ, "PYTHONPATH": str(blocker.parent)}
    args = [a.replace("{rec}", str(recording)).replace("{tmp}", str(tmp_path)) for a in argv]
    line = one_line_error(run(*args, env=env), 1)
    assert "robocli-robots[record]" in line


@pytest.mark.parametrize("argv", [["info", "{rec}"], ["export", "{rec}", "-f", "jsonl",
                                                      "-o", "{tmp}/j"]])  # fmt: skip
def test_a_reader_that_leaves_is_exit_0(argv: list[str], recording: Path, tmp_path: Path) -> None:
    """``| head -n 1``: the reader closes the pipe after one line; robocli ends quietly with
    0 (Typer's own handling said nothing and exited 1). Repeated: it was a race."""
    args = [a.replace("{rec}", str(recording)).replace("{tmp}", str(tmp_path)) for a in argv]
    for attempt in range(5):
        proc = subprocess.Popen([*ROBOCLI, *args, *(["--overwrite"] if attempt and
                                                    "export" in args else [])],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
        assert proc.stdout is not None and proc.stderr is not None
        proc.stdout.readline()
        proc.stdout.close()  # as head does after its line
        err = proc.stderr.read()
        assert proc.wait(60) == 0, err
        assert err == b"" or b"Traceback" not in err


def test_dump_laser_until_ctrl_c_ends_when_its_reader_leaves() -> None:
    proc = subprocess.Popen([*ROBOCLI, "dump", "laser", "sim", "-n", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
    assert proc.stdout is not None
    for _ in range(3):
        proc.stdout.readline()
    proc.stdout.close()
    try:
        assert proc.wait(60) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
    assert proc.stderr is not None and b"Traceback" not in proc.stderr.read()
    assert sys.executable
