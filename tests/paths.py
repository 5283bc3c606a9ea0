"""Where the tests find the repository's files (``from tests.paths import DATA``), so that a
test's place in tests/ does not decide what ``Path(__file__).parents[n]`` means."""

from __future__ import annotations

from pathlib import Path

TESTS = Path(__file__).resolve().parent
ROOT = TESTS.parent  #: the repository
DATA = TESTS / "data"  #: captured traffic, recordings and schemas the tests replay
EXAMPLES = ROOT / "examples"
SPECS = ROOT / "specs"  #: the golden vectors shared by C and Python

__all__ = ["DATA", "EXAMPLES", "ROOT", "SPECS", "TESTS"]
