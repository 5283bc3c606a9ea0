"""Help texts, choices and the messages of values a user can get wrong (issue 13, finding 17):
every option of every command says what it is, in one column; option values that have a
fixed set are choices that the shell completes; a host with non-ASCII letters, ``nan`` and a
serial port that does not exist each get a message that names what is wrong."""

from __future__ import annotations

import contextlib
import io
import os
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import typer.main

from robocli.cli import app, main
from tests.commands.helpers import one_line_error, run


def _commands(
    command: Any = None, path: tuple[str, ...] = ()
) -> Iterator[tuple[tuple[str, ...], Any]]:
    """(words, command) of every command, walked from the root."""
    command = typer.main.get_command(app) if command is None else command
    subcommands = getattr(command, "commands", None)
    if not subcommands:
        yield path, command
        return
    for name, sub in subcommands.items():
        yield from _commands(sub, (*path, name))


COMMANDS = dict(_commands())


def _help(words: tuple[str, ...]) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main([*words, "--help"]) == 0
    return out.getvalue()


def test_every_command_is_walked() -> None:
    assert len(COMMANDS) >= 25 and ("sim", "abb") in COMMANDS and ("validate",) in COMMANDS


@pytest.mark.parametrize("words", list(COMMANDS), ids=" ".join)
def test_every_option_has_a_description_in_one_column(words: tuple[str, ...]) -> None:
    text = _help(words)
    options = text.split("\nOptions:\n", 1)[1]
    columns = set()
    for param in COMMANDS[words].params:
        if not getattr(param, "opts", [""])[0].startswith("-"):
            continue  # an argument (their help is checked with the usage tests)
        description = " ".join((param.help or "").split())
        assert description, f"robocli {' '.join(words)} {'/'.join(param.opts)}: no description"
        line = next(x for x in options.splitlines() for o in param.opts
                    if re.match(rf"\s+(?:\S+, )?{re.escape(o)}\b", x))  # fmt: skip
        text_at = re.search(r"\S  +(\S)", line)  # the description, when on the option's line
        if text_at:
            columns.add(text_at.start(1))
            shown = " ".join(line[text_at.start(1) :].split())
            assert shown.startswith(description[:15]), (shown, description)
    assert len(columns) <= 1, f"descriptions start in columns {sorted(columns)}:\n{options}"


CHOICES = [  # (command, its arguments, option, choices)
    (("subscribe",), ("adc",), "--format", ["table", "csv"]),
    (("bench", "rtt"), (), "--target", ["pioneer", "arm", "hub"]),
    (("bench", "jitter"), (), "--target", ["pioneer", "arm", "laser"]),
    (("bench", "throughput"), (), "--target", ["hub"]),
    (("dump", "arm"), ("sim",), "--byte-order", ["little", "big"]),
    (("upload", "arm"), ("sim",), "--real-size", ["4", "8"]),
    (("dump", "arm"), ("sim",), "--ports", ["both", "motion", "state"]),
    (("sim", "abb"), (), "--profile", ["abb", "generic"]),
    (("upload", "arm"), ("sim",), "--shape", ["circle", "rectangle"]),
    (("traj", "circle"), (), "--plane", ["xy", "yz", "xz"]),
]


@pytest.mark.parametrize(("command", "args", "option", "choices"), CHOICES,
                         ids=[f"{' '.join(c)} {o}" for c, _, o, _ in CHOICES])  # fmt: skip
def test_option_values_are_choices_the_shell_completes(
    command: tuple[str, ...], args: tuple[str, ...], option: str, choices: list[str]
) -> None:
    line = ["robocli", *command, *args, option, ""]
    env = {**os.environ, "_ROBOCLI_COMPLETE": "complete_bash",
           "COMP_WORDS": " ".join(line), "COMP_CWORD": str(len(line) - 1)}  # fmt: skip
    proc = run(env=env)
    assert proc.returncode == 0 and proc.stdout.split() == choices, proc
    assert f"{option} [{'|'.join(choices)}]" in _help(command)
    bad = one_line_error(run(*command, *args, option, "toaster"), 2)
    listed = ", ".join(f"'{c}'" for c in choices)
    assert f"'toaster' is not one of {listed}. Try 'robocli {' '.join(command)} -h'." in bad, bad


def test_the_top_level_help_names_every_robot() -> None:
    text = _help(())
    assert all(word in text for word in ("Pioneer", "ABB", "hub", "simulator")), text


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (("connect", "pioneer", "sim", "--timeout", "nan"), "'nan' is not a finite number"),
        (("sim", "pioneer", "--sip-ms", "-inf"), "'-inf' is not a finite number"),
        (("subscribe", "adc", "--rate", "5", "--duration", "inf"), "'inf' is not a finite number"),
        (("traj", "circle", "--duration=nan"), "'nan' is not a finite number"),
    ],
)
def test_a_number_that_is_not_finite_is_named_so(args: tuple[str, ...], named: str) -> None:
    """``--timeout nan`` said "Input should be less than or equal to 3600"."""
    line = one_line_error(run(*args), 2)
    assert named in line and "less than" not in line, line


@pytest.mark.parametrize("port", ["tcp://hôst:8101", "hôst:8101"])
def test_a_host_with_non_ascii_letters_is_named_as_the_problem(port: str) -> None:
    """It said "expected tcp://HOST:PORT, PORT a number" (and without tcp://, took it for a
    serial port and nested errno): the host is what is wrong, and nothing is looked up."""
    line = one_line_error(run("connect", "pioneer", port), 2)
    assert "'hôst' is not a host name" in line, line
    assert "PORT a number" not in line and "Errno" not in line, line


@pytest.mark.parametrize("host", ["tcp://a..b:8101", "a..b"])
def test_a_name_that_is_no_host_name_is_a_usage_error(host: str) -> None:
    """An empty DNS label once ended in a UnicodeError traceback."""
    args = ("connect", "pioneer", host) if "://" in host else ("connect", "arm", host)
    line = one_line_error(run(*args, "--timeout", "1"), 2)
    assert "not a host name" in line, line


def test_a_missing_serial_port_says_why_once() -> None:
    """It nested errno three times: ``[Errno 2] could not open port X: [Errno 2] No such
    file or directory: 'X'``."""
    line = one_line_error(run("connect", "pioneer", "/dev/ttyROBOCLI_NONE"), 3)
    assert line.count("No such file or directory") == 1 and "Errno" not in line, line
    assert "robocli ports" in line
    line = one_line_error(run("connect", "pioneer", "/dev/null"), 3)
    assert "/dev/null: not a serial port" in line, line


def test_validate_calls_the_alignment_a_time_shift_not_a_delay(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The demo printed "delay 1129 ms" against the exact simulator: that was how long the
    recording ran before the arm moved (the upload), and it read like a bug."""
    from robocli.kinematics.trajlog import read_log, write_log
    from robocli.kinematics.validate import shifted

    sim, real = tmp_path / "sim.json", tmp_path / "real.json"
    assert main(["traj", "circle", "-o", str(sim)]) == 0
    write_log(shifted(read_log(sim), 1.2, pad_s=1.2), real)  # 1.2 s standing, then the circle
    capsys.readouterr()
    assert main(["validate", str(sim), str(real)]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "delay" not in out and "time shift 1200.0 ms" in out, out
    assert "the measured motion starts 1200.0 ms later in its log" in out, out
