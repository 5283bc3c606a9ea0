"""The version robocli reports, and the name it is installed by.

The distribution is ``robocli-robots`` ("robocli" on PyPI is an unrelated package); the import
package and the command stay ``robocli``. The version is the installed distribution's, which
setuptools-scm took from the git tag when it was built (``pyproject.toml``); a tree that is
not installed reports ``0+unknown``.
"""

from __future__ import annotations

from importlib import metadata

DIST_NAME = "robocli-robots"


def _installed_version() -> str:
    try:
        return metadata.version(DIST_NAME)
    except metadata.PackageNotFoundError:
        return "0+unknown"


__version__ = _installed_version()
