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


#: what the tree has that is not its own code: virtual environments, caches, build output
_NOT_SOURCE = {"build", "dist", "demo-out", "node_modules", "__pycache__"}


def _source_files(top: Path) -> list[Path]:
    """The ``.py`` files of ``top``'s folders, outside hidden, build and egg-info folders."""
    out = []
    for folder in sorted(p for p in top.iterdir() if p.is_dir()):
        if folder.name.startswith(".") or folder.name.endswith(".egg-info"):
            continue
        for path in folder.rglob("*.py"):
            parts = path.relative_to(top).parts
            if not _NOT_SOURCE.intersection(parts) and not parts[-2].startswith("."):
                out.append(path)
    return out


def _misplaced_benchmarks(top: Path) -> list[str]:
    """Benchmark suites (``test_bench_*.py``) and soak scripts (``*soak*.py``) outside the
    one top-level ``benchmarks/`` (the test suite and the package have their own rules)."""
    out = []
    for path in _source_files(top):
        rel = path.relative_to(top)
        if rel.parts[0] in ("benchmarks", "tests", "robocli"):
            continue
        if path.name.startswith("test_bench_") or "soak" in path.stem:
            out.append(rel.as_posix())
    return sorted(out)


def test_benchmarks_live_in_one_top_level_folder() -> None:
    top = ROOT.parent
    assert _misplaced_benchmarks(top) == []
    assert not (top / "bench").exists(), "bench/ beside robocli/bench: the suites are benchmarks/"
    assert not (top / "tools").exists(), "tools/: a soak goes to benchmarks/, a build file to csrc/"


def test_the_benchmark_check_sees_a_stray_suite(tmp_path: Path) -> None:
    for rel in ("benchmarks/test_bench_a.py", "benchmarks/soak_b.py", "tests/test_bench_cli.py",
                "bench/test_bench_c.py", "tools/soak_record.py", ".venv/lib/soak.py"):  # fmt: skip
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text("")
    assert _misplaced_benchmarks(tmp_path) == ["bench/test_bench_c.py", "tools/soak_record.py"]
