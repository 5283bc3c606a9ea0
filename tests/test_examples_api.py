"""The examples use robocli's public API only (what a user copies from them must work in
their own program), and examples/wander.py runs on the built-in simulator by its URL."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

from tests import paths

EXAMPLES = sorted(paths.EXAMPLES.glob("*.py"))


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.name for p in EXAMPLES])
def test_an_example_imports_no_private_module(path: Path) -> None:
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        names = []
        if isinstance(node, ast.ImportFrom) and node.module:
            names = [node.module, *(f"{node.module}.{a.name}" for a in node.names)]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        for name in names:
            if name.startswith("robocli"):
                parts = name.split(".")
                assert "commands" not in parts, f"{path.name}: imports the CLI ({name})"
                assert not any(p.startswith("_") for p in parts), f"{path.name}: {name}"


def test_wander_runs_on_a_sim_url() -> None:
    wander = paths.EXAMPLES / "wander.py"
    done = subprocess.run([sys.executable, str(wander), "sim://?time_scale=4", "--seconds", "1"],
                          capture_output=True, text=True, timeout=120)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("travelled ")
