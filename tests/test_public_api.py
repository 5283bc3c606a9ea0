"""Every public class is importable from ``robocli``, lazily: ``import robocli`` loads none
of the device, simulator or recording modules (nor numpy) until a name is used."""

from __future__ import annotations

import ast
import importlib
import inspect
import subprocess
import sys
from pathlib import Path

import pytest

import robocli

#: packages whose public classes users reach through ``robocli``
PACKAGES = [
    "robocli.devices.pioneer", "robocli.devices.arm", "robocli.devices.hub",
    "robocli.devices.laser", "robocli.devices.base", "robocli.devices.create", "robocli.errors",
    "robocli.bridge",
]  # fmt: skip
#: (package, name) taken at the top by another class of that name, reachable in its package
SHADOWED = {
    ("robocli.devices.pioneer", "LinkStats"),
}


def test_all_lists_exactly_what_resolves() -> None:
    assert robocli.__all__ == sorted(robocli.__all__)
    assert set(robocli.__all__) == {*robocli._LAZY, "__version__"}
    for name in robocli.__all__:
        assert getattr(robocli, name) is not None
    with pytest.raises(AttributeError):
        robocli.NoSuchThing  # noqa: B018


@pytest.mark.parametrize("package", PACKAGES)
def test_every_public_class_is_importable_from_robocli(package: str) -> None:
    module = importlib.import_module(package)
    for name in getattr(module, "__all__", ()):
        value = getattr(module, name)
        if not inspect.isclass(value) or (package, name) in SHADOWED:
            continue
        assert getattr(robocli, name, None) is value, f"robocli.{name} ({package})"


def test_import_robocli_stays_light() -> None:
    code = ("import sys, robocli; heavy = sorted(m for m in sys.modules if m.startswith("
            "('robocli.devices', 'robocli.sim', 'robocli.serving', 'robocli.io', "
            "'robocli.hub_server', 'numpy', 'serial', 'zenoh'))); print(heavy)")  # fmt: skip
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=60, check=True).stdout.strip()  # fmt: skip
    assert out == "[]"


def _public_classes(root: Path) -> dict[str, list[str]]:
    """Each public class name (no leading ``_``) defined at a module's top level, also under
    ``if``/``try`` (``if TYPE_CHECKING:``), in ``root``'s modules -> where it is defined."""
    found: dict[str, list[str]] = {}

    def walk(body: list[ast.stmt], where: str) -> None:
        for node in body:
            if isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
                found.setdefault(node.name, []).append(f"{where}:{node.lineno}")
            elif isinstance(node, (ast.If, ast.Try)):
                walk([*node.body, *node.orelse], where)
                for handler in getattr(node, "handlers", ()):
                    walk(handler.body, where)

    for path in sorted(root.rglob("*.py")):
        where = path.relative_to(root.parent).as_posix()
        walk(ast.parse(path.read_text(encoding="utf-8")).body, where)
    return found


def test_no_two_public_classes_share_a_name() -> None:
    """A name says which class it is: two public classes of one name (a client's and a
    server's ``Session``, two ``Scan``s) make readers and ``from ... import`` guess."""
    root = Path(robocli.__file__).parent
    shared = {name: where for name, where in _public_classes(root).items() if len(where) > 1}
    assert shared == {}


def test_the_name_check_sees_a_shared_name(tmp_path: Path) -> None:
    """The walk above does find a name defined twice (not a test that cannot fail)."""
    pkg = tmp_path / "robocli"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "a.py").write_text("class Scan:\n    pass\n\n\nclass _Private:\n    pass\n")
    (pkg / "sub" / "b.py").write_text("if True:\n    class Scan:\n        pass\n")
    (pkg / "sub" / "c.py").write_text("class _Private:\n    pass\n")
    found = _public_classes(pkg)
    assert found == {"Scan": ["robocli/a.py:1", "robocli/sub/b.py:2"]}
