"""Helpers shared by the message specs."""

from __future__ import annotations

from typing import Any


def plain(obj: Any) -> Any:
    """A parsed ``construct`` value as plain dicts/lists (private ``_io`` keys dropped)."""
    if isinstance(obj, dict):
        return {k: plain(v) for k, v in obj.items() if not k.startswith("_")}
    if isinstance(obj, list):
        return [plain(v) for v in obj]
    return obj
