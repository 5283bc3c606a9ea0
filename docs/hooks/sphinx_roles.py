"""Griffe extension: the Sphinx roles of robocli's docstrings become cross-references.

The docstrings are written for Sphinx (``:class:`Pioneer```, ``:func:`~robocli.io.record.info```,
``:mod:`.keys```); mkdocstrings renders Markdown, where a role would show as raw text. Each role
becomes an *optional* autorefs reference to the object it names, resolved as Sphinx would:
an absolute path, else a name relative to the object (its class, its module, the package
above). It is a link when that object is rendered on a page of the site, plain code
otherwise (a standard-library name, an object left out of the API pages): an optional
reference never fails a strict build. ``~`` shows the last component only, as in Sphinx.
"""

from __future__ import annotations

import re
from typing import Any

import griffe

ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|attr|data|exc|obj|const):`(~?)([^`]+)`")


def _lookup(scope: griffe.Object, path: str) -> str | None:
    """The canonical path of ``path`` seen from ``scope``, or None."""
    try:
        found = scope[path]
    except (KeyError, ValueError, griffe.AliasResolutionError, griffe.CyclicAliasError):
        return None
    try:
        return str(found.canonical_path) if found.is_alias else str(found.path)
    except (griffe.AliasResolutionError, griffe.CyclicAliasError):
        return None


def resolve(obj: griffe.Object, target: str, root: griffe.Object) -> str | None:
    """Where ``target`` (as a role in ``obj``'s docstring names it) lives, or None."""
    target = target.strip().rstrip("()")
    if target.startswith(root.name + "."):
        return _lookup(root, target[len(root.name) + 1 :])
    if target == root.name:
        return root.name
    dots = len(target) - len(target.lstrip("."))
    scope: griffe.Object | None = obj
    if dots:  # .keys: relative to the module (each extra dot: one package up)
        scope = obj.module
        for _ in range(dots - 1):
            scope = scope.parent if scope is not None else None
        return _lookup(scope, target[dots:]) if scope is not None else None
    while scope is not None:
        found = _lookup(scope, target)
        if found is not None:
            return found
        scope = scope.parent
    return None


def convert(text: str, obj: griffe.Object, root: griffe.Object) -> str:
    def role(match: re.Match[str]) -> str:
        tilde, target = match[1], match[2]
        shown = target.strip().rsplit(".", 1)[-1] if tilde else target.strip().lstrip(".")
        code = f"<code>{shown}</code>"
        path = resolve(obj, target, root)
        return f'<autoref identifier="{path}" optional>{code}</autoref>' if path else code

    return ROLE.sub(role, text)


class SphinxRoles(griffe.Extension):
    """Rewrites every docstring of the package once it is loaded."""

    def on_package(self, *, pkg: griffe.Module, **kwargs: Any) -> None:
        self._visit(pkg, pkg, set())

    def _visit(self, obj: griffe.Object, root: griffe.Object, seen: set[str]) -> None:
        if obj.path in seen:
            return
        seen.add(obj.path)
        if obj.docstring is not None:
            obj.docstring.value = convert(obj.docstring.value, obj, root)
        for member in obj.members.values():
            if not member.is_alias:
                self._visit(member, root, seen)
