"""Usage errors: exit 2, one line naming the bad value, a hint to -h; help without value
placeholders; -v after the subcommand (issue 7: 10, 12, 19)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.commands.helpers import one_line_error, run
from tests.paths import EXAMPLES


@pytest.mark.parametrize(
    ("port", "named"),
    [
        ("tcp://host:notaport", "tcp://host:notaport"),
        ("tcp://127.0.0.1:99999", "99999"),
        ("tcp://127.0.0.1:", "tcp://127.0.0.1:"),
        ("robot:", "robot:"),
        ("ftp://x", "ftp"),
        ("loop://", "loop://"),
    ],
)
def test_malformed_urls(port: str, named: str) -> None:
    line = one_line_error(run("connect", "pioneer", port, "--timeout", "1"), 2)
    assert named in line and line.endswith("Try 'robocli connect pioneer -h'."), line


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (("dump", "pioneer"), "give PORT or --file"),
        (("dump", "pioneer", "sim", "--file", "x.jsonl"), "x.jsonl"),
        (("dump", "pioneer", "--file", "/nonexistent/capture.jsonl"), "capture.jsonl"),
        (("connect", "pioneer", "sim", "--subtype", "box"), "'box'"),
        (("dump", "pioneer", "sim", "--subtype", "p3xd"), "'p3xd'"),
        (("connect", "pioneer"), "URL"),
        (("connect", "pioneer", "sim", "--baud", "fast"), "fast"),
    ],
)
def test_usage_errors_name_the_value(args: tuple[str, ...], named: str) -> None:
    line = one_line_error(run(*args), 2)
    assert named in line and line.endswith(f"Try 'robocli {args[0]} pioneer -h'."), line


def test_both_port_and_file(tmp_path: Path) -> None:
    capture = tmp_path / "c.jsonl"
    capture.write_text("")
    line = one_line_error(run("dump", "pioneer", "sim", "--file", str(capture)), 2)
    assert "give PORT or --file, not both" in line


def test_output_over_the_file_being_read_is_refused(tmp_path: Path) -> None:
    capture = tmp_path / "c.jsonl"
    text = (EXAMPLES / "pioneer_drive.jsonl").read_text()
    capture.write_text(text)
    line = one_line_error(
        run("dump", "pioneer", "--file", str(capture), "--output", str(capture)), 2
    )
    assert "would be emptied" in line and capture.read_text() == text  # untouched


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (("connect", "pioneer", "sim", "--timeout", "inf"), "inf"),
        (("sim", "pioneer", "--port", "65535", "--robots", "3"), "65535"),
    ],
)
def test_out_of_range_values(args: tuple[str, ...], named: str) -> None:
    line = one_line_error(run(*args), 2)
    assert named in line, line


@pytest.mark.parametrize("words", [(), ("connect",), ("bench",), ("sim",)])
def test_a_group_without_its_command_shows_its_help(words: tuple[str, ...]) -> None:
    proc = run(*words)
    assert proc.returncode == 0 and proc.stdout.startswith("Usage: robocli"), proc
    assert ("Commands:" if words else "Robots:") in proc.stdout  # the root: by panels


@pytest.mark.parametrize(
    ("content", "named"),
    [
        (b"\xff\xfe{\x00w\x00", "not UTF-8"),  # UTF-16 with its byte order mark
        (b'{"walls": [[0, 0, 1, 1]', "not valid JSON"),
        (b"0 0 1\n", "'0 0 1'"),
    ],
)
def test_sim_rejects_a_bad_map(tmp_path: Path, content: bytes, named: str) -> None:
    path = tmp_path / ("lab.txt" if content.startswith(b"0") else "lab.json")
    path.write_bytes(content)
    line = one_line_error(run("sim", "pioneer", "--port", "0", "--map", str(path)), 2)
    assert named in line and path.name in line, line


@pytest.mark.parametrize(
    "command",
    [("connect", "pioneer"), ("dump", "pioneer"), ("ports",), ("sim", "pioneer"), ("bench", "sip")],
)
def test_help_shows_no_value_placeholders(command: tuple[str, ...]) -> None:
    proc = run(*command, "-h")
    assert proc.returncode == 0 and proc.stderr == ""
    assert not re.search(r"<[a-z ]+>|\{\w+\}", proc.stdout), proc.stdout
    options = {m[1]: m[2] for m in re.finditer(r"(--[\w-]+)(?: ([A-Z][\w/.]*))?", proc.stdout)}
    assert options.get("--json", "") is None or "--json" not in options  # a flag: no value
    if command[0] == "sim":
        assert options["--port"] == "INTEGER" and options["--pty"] is None
    if command[0] in ("connect", "dump"):
        assert f"Usage: robocli {' '.join(command)} [OPTIONS]" in proc.stdout
        assert proc.stdout.splitlines()[0].endswith(("] URL", "[URL]"))
    assert "╭" not in proc.stdout  # plain text, whatever the terminal


def test_verbose_after_the_subcommand() -> None:
    proc = run("connect", "pioneer", "sim", "--once", "-v")
    assert proc.returncode == 0, proc.stderr
    assert "INFO" in proc.stderr and "pose" in proc.stdout
    assert run("connect", "pioneer", "sim", "--once", "-vv").returncode == 0


@pytest.mark.parametrize(
    ("command", "targets"),
    [("rtt", "pioneer, arm, hub"), ("jitter", "pioneer, arm, laser"), ("sip", "pioneer")],
)
def test_an_unknown_bench_target_lists_what_that_bench_measures(command: str, targets: str) -> None:
    line = one_line_error(run("bench", command, "--target", "robotx"), 2)
    listed = ", ".join(f"'{t}'" for t in targets.split(", "))
    assert line.endswith(f"is not one of {listed}. Try 'robocli bench {command} -h'."), line
