"""One grammar for every command (docs/cli-grammar.md): a walk over every command's
parameters and -h, through the Typer app itself, so that a command added later is checked
without being named here."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from typing import Any

import pytest

from robocli.cli import SHORT_HELP, build_command
from robocli.commands._options import RENAMED, renamed

#: Options whose one name is fixed by the grammar: a command that has the thing has this name.
SHARED = {"--output": "-o", "--count": "-n", "--duration": "-d", "--rate": "-r"}
#: Old spellings that no visible option may have.
RETIRED = {"--out", "--seconds", "--samples", "--points", "--n", "--url", "--monitor"}
#: Option names that are devices of a multi-device command (the same name everywhere).
DEVICE_OPTIONS = {"--pioneer", "--arm", "--hub", "--laser"}
#: Parameters that take a free-form value with a fixed set of meanings are choices.
ENUMERATED = {"--format", "--byte-order", "--real-size", "--profile", "--model", "--target",
              "--compression", "--ports", "--plane", "--shape"}  # fmt: skip


def _commands() -> Iterator[tuple[str, Any]]:
    def walk(cmd: Any, path: str) -> Iterator[tuple[str, Any]]:
        for name, sub in cmd.commands.items():
            full = f"{path} {name}".strip()
            if hasattr(sub, "commands"):
                yield from walk(sub, full)
            else:
                yield full, sub

    yield from walk(build_command(), "")


COMMANDS = dict(_commands())


def _visible(cmd: Any) -> list[Any]:
    return [p for p in cmd.params if not getattr(p, "hidden", False)]


@pytest.mark.parametrize("path", sorted(COMMANDS))
def test_every_option_follows_the_grammar(path: str) -> None:
    cmd = COMMANDS[path]
    for param in _visible(cmd):
        names = set(param.opts + param.secondary_opts)
        assert not names & RETIRED, f"{path}: {names & RETIRED} is retired"
        for long, short in SHARED.items():
            if long in names:
                assert short in names, f"{path}: {long} without {short}"
            elif short in names:
                raise AssertionError(f"{path}: {short} is {long} everywhere, not {names}")
        if "--json" in names:  # one meaning: a line per object
            assert "JSON Lines" in (param.help or "") or "One line" in (param.help or ""), path
        if names & ENUMERATED:
            td = param.type_descriptor
            assert td.choices, f"{path}: {names} is not a choice"
        first = next((p for p in cmd.params if p.param_type_name == "argument"), None)
        if param is first and param.name in ("port", "host", "url", "hub"):
            assert param.metavar in ("URL", "[URL]"), f"{path}: the device is a URL positional"
        if names & DEVICE_OPTIONS and not param.is_flag:
            assert param.metavar == "URL", f"{path}: {names} names a device by URL"


@pytest.mark.parametrize("path", sorted(COMMANDS))
def test_every_arm_command_takes_both_ports(path: str) -> None:
    names = {o for p in COMMANDS[path].params for o in p.opts}
    if "--state-port" in names:
        assert "--motion-port" in names, f"{path} has --state-port but not --motion-port"


def test_every_command_has_its_whole_short_help() -> None:
    assert set(SHORT_HELP) == set(COMMANDS)


def test_help_is_grouped_and_nothing_is_cut() -> None:
    from robocli.cli import main

    proc = subprocess.run([sys.executable, "-m", "robocli", "-h"], capture_output=True,
                          text=True, timeout=60)  # fmt: skip
    assert proc.returncode == 0
    for panel in ("Robots:", "Sensors:", "Recording and replay:", "Lab:", "Tools:"):
        assert panel in proc.stdout
    assert "..." not in _without_usage(proc.stdout)
    assert callable(main)


def _without_usage(text: str) -> str:
    """Help without its usage line (whose ``[ARGS]...`` is Click's, not a cut)."""
    return "\n".join(line for line in text.splitlines() if not line.startswith("Usage:"))


@pytest.mark.parametrize("path", sorted(COMMANDS))
def test_no_help_is_cut(path: str, capsys: pytest.CaptureFixture[str]) -> None:
    from robocli.cli import main

    group = path.split()[0]
    if group == path:
        return
    assert main([group, "-h"]) == 0
    assert "..." not in _without_usage(capsys.readouterr().out)


def test_old_spellings_are_rewritten_with_a_notice(capsys: pytest.CaptureFixture[str]) -> None:
    assert renamed("traj circle", ["--out", "x.json", "--points=5"]) == [
        "--output", "x.json", "--count=5",
    ]  # fmt: skip
    assert renamed("bench rtt", ["--url", "tcp://h:1", "-n", "3"]) == ["tcp://h:1", "-n", "3"]
    assert renamed("subscribe", ["imu", "-f", "jsonl"]) == ["imu", "--json"]
    assert renamed("subscribe", ["computer", "-r", "5"]) == ["sysinfo", "-r", "5"]
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 5 and all(line.startswith("robocli: ") for line in err)
    assert all(command in COMMANDS for command in RENAMED)


def _complete(words: str, shell: str) -> list[str]:
    """What the shell's completion script asks robocli for ``words`` (the last one being
    completed): Typer's ``_ROBOCLI_COMPLETE`` protocol, as bash, zsh and fish call it."""
    parts = words.split(" ")
    env = {**os.environ, "_ROBOCLI_COMPLETE": f"complete_{shell}", "_TYPER_COMPLETE_ARGS": words,
           "COMP_WORDS": words, "COMP_CWORD": str(len(parts) - 1),
           "_TYPER_COMPLETE_FISH_ACTION": "get-args"}  # fmt: skip
    proc = subprocess.run([sys.executable, "-m", "robocli"], env=env, capture_output=True,
                          text=True, timeout=60)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    return proc.stdout.split()


@pytest.mark.parametrize("shell", ["bash", "zsh", "fish"])
@pytest.mark.parametrize(
    ("words", "expected"),
    [
        ("robocli export run.mcap -f ", {"csv", "jsonl", "npz", "irb120-json"}),
        ("robocli record --compression ", {"zstd", "lz4", "none"}),
        ("robocli connect laser sim --model ", {"urg-04lx", "utm-30lx", "ust-10lx"}),
        ("robocli subscribe ", {"adc", "imu", "sysinfo", "laser", "depth", "stereo"}),
    ],
)
def test_choices_complete_in_every_shell(shell: str, words: str, expected: set[str]) -> None:
    got = " ".join(_complete(words, shell))
    for value in expected:
        assert value in got, (shell, words, got)


def test_the_choices_are_the_librarys() -> None:
    """A choice spelled in the CLI (for completion) names what the library accepts."""
    from typing import get_args

    from robocli.commands import export, hub, laser, record
    from robocli.io.export import FORMATS
    from robocli.io.record import COMPRESSIONS
    from robocli.protocols.ros4mat import sensor_type

    assert get_args(export.Format) == FORMATS
    assert get_args(record.Compression) == COMPRESSIONS
    assert get_args(laser.Model) == laser.MODELS
    for name in hub.SENSOR_NAMES:
        sensor_type(name)  # each is a sensor the protocol knows
