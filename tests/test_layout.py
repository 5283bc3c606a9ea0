"""The package's layout keeps its rules (shared/design.md): no import circles, not even
through imports made only for type checking or inside functions."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "robocli"


#: the compiled modules of the package (the C core), imported like the others
_EXTENSIONS = {f"robocli.{p.name.split('.')[0]}" for p in [*ROOT.glob("*.so"), *ROOT.glob("*.pyd")]}


def _modules() -> dict[str, Path]:
    found = {}
    for path in ROOT.rglob("*.py"):
        name = ".".join(path.relative_to(ROOT.parent).with_suffix("").parts)
        found[name.removesuffix(".__init__")] = path
    return found


def _targets(name: str, path: Path, node: ast.Import | ast.ImportFrom,
             modules: dict[str, Path]) -> list[str]:  # fmt: skip
    """The robocli modules (or the package's own ``__init__``, ``robocli``) that one import
    statement of module ``name`` loads."""

    def resolve(target: str) -> str | None:
        while target and target not in modules and target not in {"robocli", *_EXTENSIONS}:
            target = target.rpartition(".")[0]
        return target or None

    if isinstance(node, ast.Import):
        targets = [alias.name for alias in node.names]
    else:
        base = node.module or ""
        if node.level:
            package = name if path.name == "__init__.py" else name.rpartition(".")[0]
            for _ in range(node.level - 1):
                package = package.rpartition(".")[0]
            base = f"{package}.{base}" if base else package
        targets = [base, *(f"{base}.{alias.name}" for alias in node.names)]
        if base == "robocli":  # `from robocli import x`: the module x, else the __init__'s x
            targets = [t for t in targets[1:] if t in modules or t in _EXTENSIONS] or [base]
    found = {resolve(t) for t in targets if t == "robocli" or t.startswith("robocli.")}
    return sorted(f for f in found if f)


def _imports(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The robocli modules that ``name`` imports anywhere in its file (a package's own
    ``__init__`` is not counted: importing a submodule runs it anyway)."""
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            for found in _targets(name, path, node, modules):
                if found in modules and found != name and not name.startswith(found + "."):
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


# ---------------------------------------------------------------- packages

LAYOUT = ROOT.parent / "docs" / "development.md"


def _package(module: str) -> str:
    """The top-level part of robocli a module belongs to: ``robocli.io.record.reader`` is in
    ``robocli.io``; a top-level module (``robocli.transports``) and the package's own
    ``__init__`` (``robocli``) stand for themselves."""
    return ".".join(module.split(".")[:2])


def _import_sites(name: str, path: Path, modules: dict[str, Path]) -> list[tuple[str, int]]:
    """(robocli module, line) of every import in the file of module ``name``, at module level,
    in a function or under ``TYPE_CHECKING`` alike; ``from robocli import X`` counts as an
    import of ``robocli.X`` when that is a module, else of the package's ``__init__``."""
    sites = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            sites += [(target, node.lineno) for target in _targets(name, path, node, modules)]
    return sites


def package_graph(modules: dict[str, Path]) -> dict[tuple[str, str], list[str]]:
    """(importing package, imported package) -> the ``file:line`` of each import that makes
    the edge, over every module of ``modules``."""
    edges: dict[tuple[str, str], list[str]] = {}
    for name, path in sorted(modules.items()):
        where = path.relative_to(ROOT.parent) if path.is_relative_to(ROOT.parent) else path
        for target, line in _import_sites(name, path, modules):
            edge = (_package(name), _package(target))
            if edge[0] != edge[1] and f"{where}:{line}" not in edges.get(edge, []):
                edges.setdefault(edge, []).append(f"{where}:{line}")
    return edges


def _graph(edges: dict[tuple[str, str], list[str]]) -> dict[str, list[str]]:
    graph: dict[str, list[str]] = {}
    for a, b in sorted(edges):
        graph.setdefault(a, []).append(b)
        graph.setdefault(b, [])
    return graph


def package_knots(edges: dict[tuple[str, str], list[str]]) -> list[set[str]]:
    """The groups of packages that all import one another, however indirectly (the strongly
    connected groups of more than one; Tarjan's algorithm, iterative)."""
    graph = _graph(edges)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    groups: list[set[str]] = []
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(graph[root]))]
        index[root] = low[root] = len(index)
        stack.append(root)
        while work:
            node, nexts = work[-1]
            nxt = next(nexts, None)
            if nxt is None:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    group = set()
                    while (member := stack.pop()) != node:
                        group.add(member)
                    groups.append(group | {node})
            elif nxt not in index:
                index[nxt] = low[nxt] = len(index)
                stack.append(nxt)
                work.append((nxt, iter(graph[nxt])))
            elif nxt in stack:
                low[node] = min(low[node], index[nxt])
    return [g for g in groups if len(g) > 1]


def package_cycles(edges: dict[tuple[str, str], list[str]]) -> list[list[str]]:
    """One cycle (its packages in order, the first repeated last) through each knot of
    :func:`package_knots`."""
    graph = _graph(edges)
    cycles = []
    for group in package_knots(edges):
        start = min(group)  # a shortest path back to it, inside the group (breadth first)
        trails = {b: [start, b] for b in graph[start] if b in group}
        frontier = list(trails)
        while start not in trails:
            node = frontier.pop(0)
            for b in graph[node]:
                if b in group and b not in trails:
                    trails[b] = [*trails[node], b]
                    frontier.append(b)
        cycles.append(trails[start])
    return cycles


def _explain(edges: dict[tuple[str, str], list[str]], cycle: list[str]) -> str:
    knot = next(k for k in package_knots(edges) if cycle[0] in k)
    members = ", ".join(sorted(knot))
    lines = [f"{' -> '.join(cycle)}   ({len(knot)} packages import one another: {members})"]
    for a, b in zip(cycle, cycle[1:], strict=False):
        lines.append(f"  {a} -> {b}: {', '.join(edges[a, b][:8])}")
    return "\n".join(lines)


def test_no_package_cycles() -> None:
    """No two parts of robocli import each other, however indirectly: a part can be read,
    tested and moved with only what is below it."""
    edges = package_graph(_modules())
    cycles = package_cycles(edges)
    assert cycles == [], "\n".join(_explain(edges, cycle) for cycle in cycles)


def layers(text: str) -> list[list[str]]:
    """The layer order of the layout page: the numbered list between ``<!-- layers -->`` and
    ``<!-- /layers -->``, one layer a line, its packages the backquoted names before the
    line's first colon (without ``robocli.``)."""
    section = text.split("<!-- layers -->", 1)[1].split("<!-- /layers -->", 1)[0]
    found = []
    for line in section.splitlines():
        head, _, _ = line.partition(":")
        if head.lstrip()[:1].isdigit():
            found.append(["robocli" if n == "robocli" else f"robocli.{n}"
                          for n in re.findall(r"`([\w.]+)`", head)])  # fmt: skip
    return found


def layer_breaches(edges: dict[tuple[str, str], list[str]],
                   order: list[list[str]]) -> list[str]:  # fmt: skip
    """Each import of a package from its own layer or one above it, and each package that
    the order does not place."""
    rank = {name: i for i, layer in enumerate(order) for name in layer}
    out = [f"{p} is in no layer of docs/development.md"
           for p in sorted({p for edge in edges for p in edge} - rank.keys())]  # fmt: skip
    for (a, b), sites in sorted(edges.items()):
        if a in rank and b in rank and rank[a] <= rank[b]:
            out.append(f"{a} (layer {rank[a] + 1}) imports {b} (layer {rank[b] + 1}): "
                       + ", ".join(sites[:8]))  # fmt: skip
    return out


def test_packages_keep_the_documented_layers() -> None:
    """A package imports only packages of the layers below its own, in the order that
    docs/development.md gives a maintainer."""
    order = layers(LAYOUT.read_text(encoding="utf-8"))
    assert len(order) > 5
    breaches = layer_breaches(package_graph(_modules()), order)
    assert breaches == [], "\n".join(breaches)


def test_the_checker_sees_a_package_cycle(tmp_path: Path) -> None:
    """The package graph finds a cycle made by an import inside a function and one made only
    for the type checker, names the lines that make it, and the layers see the breach."""
    pkg = tmp_path / "robocli"
    for sub in ("low", "high"):
        (pkg / sub).mkdir(parents=True)
        (pkg / sub / "__init__.py").write_text("")
    (pkg / "low" / "a.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from robocli.high.b import x\n"
    )
    (pkg / "high" / "b.py").write_text("def f():\n    from ..low import a\n")
    (pkg / "top.py").write_text("from robocli import high\n")
    modules = {
        "robocli.low": pkg / "low" / "__init__.py", "robocli.low.a": pkg / "low" / "a.py",
        "robocli.high": pkg / "high" / "__init__.py", "robocli.high.b": pkg / "high" / "b.py",
        "robocli.top": pkg / "top.py",
    }  # fmt: skip
    edges = package_graph(modules)
    assert edges == {
        ("robocli.low", "robocli.high"): [f"{pkg / 'low' / 'a.py'}:3"],
        ("robocli.high", "robocli.low"): [f"{pkg / 'high' / 'b.py'}:2"],
        ("robocli.top", "robocli.high"): [f"{pkg / 'top.py'}:1"],
    }
    assert package_cycles(edges) == [["robocli.high", "robocli.low", "robocli.high"]]
    assert "b.py:2" in _explain(edges, package_cycles(edges)[0])
    order = layers("<!-- layers -->\n1. `low`: x\n2. `high`, `top`: y\n<!-- /layers -->")
    assert order == [["robocli.low"], ["robocli.high", "robocli.top"]]
    assert layer_breaches(edges, order) == [
        f"robocli.low (layer 1) imports robocli.high (layer 2): {pkg / 'low' / 'a.py'}:3",
        f"robocli.top (layer 2) imports robocli.high (layer 2): {pkg / 'top.py'}:1",
    ]


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
