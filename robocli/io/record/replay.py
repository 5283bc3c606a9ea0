"""A recording as the packets a simulator replays (``robocli sim pioneer|abb --replay``):
:class:`RecordedPackets` is the :class:`~robocli.sim.replay.PacketSource` of an MCAP file."""

from __future__ import annotations

from pathlib import Path

from robocli.errors import RobocliError
from robocli.io.record.links import is_raw
from robocli.io.record.reader import info, raw_frames

__all__ = ["RecordedPackets"]


class RecordedPackets:
    """The raw frames of the recording at ``path`` (read when asked, not held)."""

    def __init__(self, path: str | Path) -> None:
        self.path = path

    @property
    def name(self) -> str:
        return str(self.path)

    def frames(self, protocol: str, direction: str) -> list[tuple[float, bytes]]:
        """``(t, frame)`` of the first ``protocol`` link's raw frames going ``direction``,
        ``t`` in seconds since the recording's first message."""
        frames = [(t, f) for t, way, f in raw_frames(self.path, protocol) if way == direction]
        if not frames:
            raise RobocliError(f"{self.path}: no {direction} frame of the {protocol} link "
                               "to replay")  # fmt: skip
        return frames

    def link_metadata(self, protocol: str) -> dict[str, str]:
        """The metadata of the first raw channel whose protocol starts with ``protocol``
        (``sm``: ``sm-le`` or ``sm-be``)."""
        for channel in info(self.path).channels:
            meta = channel.metadata
            if is_raw(channel.encoding, channel.schema) and meta.get("protocol", "").startswith(
                protocol
            ):
                return dict(meta)
        return {}
