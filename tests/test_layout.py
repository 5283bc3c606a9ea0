"""The package's layout keeps its rules (shared/design.md): no import circles, not even
through imports made only for type checking or inside functions."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "robocli"


def _modules() -> dict[str, Path]:
    found = {}
    for path in ROOT.rglob("*.py"):
        name = ".".join(path.relative_to(ROOT.parent).with_suffix("").parts)
        found[name.removesuffix(".__init__")] = path
    return found


def _imports(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The robocli modules that ``name`` imports anywhere in its file (a package's own
    ``__init__`` is not counted: importing a submodule runs it anyway)."""

    def resolve(target: str) -> str | None:
        while target and target not in modules:
            target = target.rpartition(".")[0]
        return target or None

    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                package = name if path.name == "__init__.py" else name.rpartition(".")[0]
                for _ in range(node.level - 1):
                    package = package.rpartition(".")[0]
                base = f"{package}.{base}" if base else package
            targets = [base, *(f"{base}.{alias.name}" for alias in node.names)]
        for target in targets:
            found = resolve(target) if target.startswith("robocli") else None
            if found and found != name and found != "robocli" and not name.startswith(found + "."):
                out.add(found)
    return out


def test_no_import_circles() -> None:
    modules = _modules()
    graph = {name: _imports(name, path, modules) for name, path in modules.items()}
    circles = []
    for start in graph:  # a path back to `start` through its imports is a circle
        seen, stack = set(), [(start, [start])]
        while stack:
            node, trail = stack.pop()
            for nxt in graph[node]:
                if nxt == start:
                    circles.append(" -> ".join([*trail, start]))
                elif nxt not in seen:
                    seen.add(nxt)
                    stack.append((nxt, [*trail, nxt]))
    assert circles == [], "\n".join(sorted(set(circles))[:10])


def test_the_checker_sees_a_circle(tmp_path: Path) -> None:
    """The graph above does find a circle where there is one (not a test that cannot fail)."""
    pkg = tmp_path / "robocli"
    pkg.mkdir()
    (pkg / "a.py").write_text("from robocli import b\n")
    (pkg / "b.py").write_text("def f():\n    from robocli.a import x\n")
    modules = {"robocli.a": pkg / "a.py", "robocli.b": pkg / "b.py"}
    assert _imports("robocli.a", pkg / "a.py", modules) == {"robocli.b"}
    assert _imports("robocli.b", pkg / "b.py", modules) == {"robocli.a"}


#: The most lines a module of robocli/ may have (shared/design.md: past about 500, a module
#: is doing two jobs; split it along a seam and re-export what outside code imports).
MAX_LINES = 500
#: Modules allowed past MAX_LINES for now, by path below robocli/ (none).
KNOWN_LONG: frozenset[str] = frozenset()


def _too_long(root: Path, limit: int) -> dict[str, int]:
    lengths = {
        path.relative_to(root).as_posix(): len(path.read_text(encoding="utf-8").splitlines())
        for path in root.rglob("*.py")
    }
    return {name: n for name, n in sorted(lengths.items()) if n > limit}


def test_no_module_passes_500_lines() -> None:
    long = {name: n for name, n in _too_long(ROOT, MAX_LINES).items() if name not in KNOWN_LONG}
    assert long == {}, f"modules over {MAX_LINES} lines (split each): {long}"


def test_the_length_check_sees_a_long_module(tmp_path: Path) -> None:
    (tmp_path / "short.py").write_text("x = 1\n" * MAX_LINES)
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "long.py").write_text("x = 1\n" * (MAX_LINES + 1))
    assert _too_long(tmp_path, MAX_LINES) == {"sub/long.py": MAX_LINES + 1}
