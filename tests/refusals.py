"""A file that robocli refuses: written, read, and the typed error it gave (one line naming
the file is the rule each caller asserts)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest


def refused(
    path: Path, text: str, read: Callable[[Path], Any], error: type[Exception], match: str
) -> Exception:
    """The ``error`` (its message matching ``match``) that ``read`` raises on ``path``
    holding ``text``."""
    path.write_text(text)
    with pytest.raises(error, match=match) as info:
        read(path)
    return info.value
