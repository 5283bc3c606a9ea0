"""Recording an arm while the CLI uploads to it: a deferred :class:`Recorder` and the raw
listeners that record both of its ports from their first byte."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from robocli.io.record.arm import arm_links
from robocli.io.record.recorder import Recorder

__all__ = ["upload_recorder"]


def upload_recorder(path: str | Path, *, byte_order: str = "little", real_size: int = 4,
                    overwrite: bool = False, ros2: bool = False,
                    ) -> tuple[Any, dict[str, list[Any]]]:  # fmt: skip
    """A :class:`~robocli.io.record.Recorder` for an upload's connection (not begun: ``add``
    the arm, then ``begin()`` once connected, so that a refused connection makes no file)
    and the listeners to give :meth:`Arm.connect`, so that both ports are recorded as
    ``arm`` from their first byte. A file it may not write is refused now."""
    rec = Recorder(path, overwrite=overwrite, deferred=True, ros2=ros2)
    _, links = arm_links(rec, "arm", byte_order=byte_order, real_size=real_size)
    return rec, {port: [raw] for port, raw in links.items()}
