"""The README's front page and the manual name files that ship and commands that run (issue 7:
20, issue 23: the README's tour runs line by line)."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

from tests.commands.helpers import run

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text(encoding="utf-8")
MANUAL = "\n".join(p.read_text(encoding="utf-8") for p in sorted((ROOT / "docs").rglob("*.md")))


def test_every_example_file_the_readme_and_the_manual_name_exists() -> None:
    named = set(re.findall(r"examples/[\w./-]+\.\w+", README + MANUAL))
    assert {"examples/lab.json", "examples/pioneer_drive.jsonl"} <= named
    assert [name for name in named if not (ROOT / name).is_file()] == []


def test_the_lab_map_loads_and_the_shipped_capture_decodes() -> None:
    from robocli.sim.world import World

    world = World.load(ROOT / "examples" / "lab.json")
    assert len(world.walls) >= 4 and world.start == (0.0, 0.0, 0.0)
    proc = run("dump", "pioneer", "--file", str(ROOT / "examples" / "pioneer_drive.jsonl"))
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    names = [line.split()[2] for line in proc.stdout.splitlines()]
    assert names[:6] == ["SYNC0", "SYNC0-reply", "SYNC1", "SYNC1-reply", "SYNC2", "SYNC2-reply"]
    assert {"ENABLE", "VEL", "RVEL", "SIP", "CLOSE"} <= set(names)


def test_readme_says_how_to_get_robocli_on_path() -> None:
    assert ". .venv/bin/activate" in README and "pip install ." in README


def test_the_readme_is_a_front_page() -> None:
    assert len(README.splitlines()) <= 200
    assert "pip install robocli-robots" in README  # the distribution's name, not PyPI's robocli


def _tour() -> list[str]:
    block = README.split("## A ten-line tour", 1)[1].split("```sh\n", 1)[1].split("```", 1)[0]
    return [line.split("#", 1)[0].strip() for line in block.splitlines() if line.strip()]


def test_every_line_of_the_readme_tour_runs(tmp_path: Path) -> None:
    """Each command of the tour, as written, from a folder holding the examples: exit 0 and
    nothing on stderr. The files it writes (circle.json, run.mcap) are read by later lines."""
    lines = _tour()
    assert len(lines) == 10
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    for line in lines:
        argv = shlex.split(line)
        assert argv[0] == "robocli", line
        proc = run(*argv[1:], cwd=tmp_path, timeout=120)
        assert proc.returncode == 0, f"{line}: exit {proc.returncode}: {proc.stderr}"
    assert (tmp_path / "circle.json").is_file() and (tmp_path / "run.mcap").is_file()


def test_the_readme_names_the_exit_codes_of_the_manual() -> None:
    """The README's one-line summary of the exit codes names the codes of the manual's table."""
    table = MANUAL.split("## Exit codes", 1)[1].split("\n#", 1)[0]
    codes = set(re.findall(r"^\| (\d+) \|", table, flags=re.M))
    summary = README.split("exit codes are stable:", 1)[1].split(".", 1)[0]
    assert codes == set(re.findall(r"\b(\d+) [a-z]", summary)), summary
