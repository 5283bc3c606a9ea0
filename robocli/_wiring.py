"""What a lower part of robocli uses but only a higher one can make, handed down at import.

``robocli/__init__.py`` runs before any module of the package, so what it puts here is
there whenever a module looks. ``Hub.connect("sim://")`` (a device client) starts the hub
server, which stands on the device clients (its sources read real robots): the clients
cannot import it (docs/development.md, Layers), so the package's ``__init__`` gives them the
starter. Nothing here imports any of robocli.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

__all__ = ["SIMULATORS"]

#: ``sim://`` simulators by device (``hub``) that :mod:`robocli.devices.simulators` starts
#: without importing them: each ``(url, **options) -> Simulator``.
SIMULATORS: dict[str, Callable[..., Any]] = {}
