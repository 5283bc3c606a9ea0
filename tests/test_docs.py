"""The documentation site (issue 23): its pages are in the repository, the docstrings' Sphinx
roles become cross-references, the CLI reference is the application's own help, and a
broken link fails ``make docs``."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
HOOKS = ROOT / "docs" / "hooks"


def test_every_note_the_code_points_to_is_a_page_of_the_site() -> None:
    """Docstrings and comments cite the protocol notes as docs/protocols/*.md: each exists, and
    none points to notes outside the repository (they were in a shared folder once)."""
    named: set[str] = set()
    outside = "shared/" + "protocols"  # spelt apart: this file names it
    for path in [*(ROOT / "robocli").rglob("*.py"), *(ROOT / "tests").rglob("*.py")]:
        text = path.read_text(encoding="utf-8")
        assert outside not in text, path
        named |= set(re.findall(r"docs/protocols/[\w-]+\.md", text))
    assert len(named) >= 5
    assert sorted(n for n in named if not (ROOT / n).is_file()) == []


def test_sphinx_roles_become_optional_cross_references() -> None:
    griffe = pytest.importorskip("griffe", reason="the docs extra is not installed")
    sys.path.insert(0, str(HOOKS))
    try:
        from sphinx_roles import SphinxRoles
    finally:
        sys.path.remove(str(HOOKS))
    extensions = griffe.load_extensions(SphinxRoles())
    errors = griffe.load("robocli.errors", search_paths=[str(ROOT)], extensions=extensions)
    text = errors.docstring.value
    assert ":class:" not in text and ":attr:" not in text, text
    # a name relative to the module, and an attribute of a class in it
    assert '<autoref identifier="robocli.errors.RobocliError" optional>' in text, text
    assert '<autoref identifier="robocli.errors.RobocliError.exit_code" optional>' in text


def test_the_cli_reference_is_every_commands_help() -> None:
    pytest.importorskip("mkdocs", reason="the docs extra is not installed")
    sys.path.insert(0, str(HOOKS))
    try:
        from cli_reference import MARKER, on_page_markdown
    finally:
        sys.path.remove(str(HOOKS))
    page = on_page_markdown(f"# CLI\n\n{MARKER}\n", page=None)
    titles = re.findall(r"^#+ `(robocli[^`]*)`", page, flags=re.M)
    for command in ("robocli", "robocli connect pioneer", "robocli sim abb", "robocli record",
                    "robocli bench rtt", "robocli traj circle", "robocli bridge arm"):  # fmt: skip
        assert command in titles
    assert "Usage: robocli connect pioneer [OPTIONS] URL" in page
    assert "--once" in page.split("`robocli connect pioneer`", 1)[1].split("\n#", 1)[0]


def test_a_broken_link_fails_the_strict_build(tmp_path: Path) -> None:
    """The site's configuration makes mkdocs --strict fail on a link to a page that is not
    there (a copy of the site, with one link broken)."""
    pytest.importorskip("mkdocs", reason="the docs extra is not installed")
    site = tmp_path / "site"
    shutil.copytree(ROOT / "docs", site / "docs")
    for name in ("mkdocs.yml", "CHANGELOG.md"):
        shutil.copy2(ROOT / name, site / name)
    index = site / "docs" / "index.md"
    index.write_text(index.read_text(encoding="utf-8") + "\n[gone](no-such-page.md)\n")
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "out")],
        cwd=site, capture_output=True, text=True, timeout=300, stdin=subprocess.DEVNULL,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1", "PYTHONPATH": str(ROOT)},
    )  # fmt: skip
    assert proc.returncode != 0, proc.stderr[-3000:]
    assert "no-such-page.md" in proc.stderr, proc.stderr[-3000:]
