"""The README's tour names files that ship and commands that run (issue 7: 20)."""

from __future__ import annotations

import re
from pathlib import Path

from cli.helpers import run

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text(encoding="utf-8")


def test_every_example_file_the_readme_names_exists() -> None:
    named = set(re.findall(r"examples/[\w./-]+\.\w+", README))
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
