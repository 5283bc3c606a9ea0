"""An arm controller that plays a recording back (``robocli sim abb --replay FILE.mcap``).

The recorded state-port stream (JOINT_POSITION, ROBOT_STATUS, JOINT_FEEDBACK: every frame
the controller sent there, byte for byte) is sent again to the state-port client on its
recorded spacing (the recording's receive times; ``speed`` times as fast), from its first
frame each time a state client connects (one at a time, as the simulator), and with
``loop`` again at its end. The wire variant (byte order, real size) is the recording's.
The motion port answers as the simulator's does (a trajectory is acknowledged and accepted)
but nothing moves: the state stream is the recording's.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from robocli.serving.server import Link
from robocli.sim.abb.server import AbbSim
from robocli.sim.replay import FrameSchedule, PacketSource

__all__ = ["AbbReplay"]

TICK_S = 0.002  #: how often the stream is checked for frames due (wall s)


def _wire(source: PacketSource) -> tuple[Any, Any]:
    """(byte order, real size) of the recorded arm link."""
    meta = source.link_metadata("sm")
    order = ">" if meta.get("byte_order") == "big" or meta.get("protocol") == "sm-be" else "<"
    return order, 8 if meta.get("real_size") == "8" else 4


class AbbReplay(AbbSim):
    """:class:`~robocli.sim.abb.server.AbbSim`'s two ports playing back the arm recorded in
    ``source`` on the state port (see the module docstring; a recording's is
    ``RecordedPackets(path)`` of :mod:`robocli.io.record.replay`). Keyword arguments go to
    :class:`AbbSim` (``robot``...)."""

    def __init__(self, source: PacketSource, *, speed: float = 1.0, loop: bool = False,
                 **options: Any) -> None:  # fmt: skip
        frames = source.frames("sm", "rx:state")
        self.schedule = FrameSchedule(frames, speed, loop)
        order, real = _wire(source)
        options.setdefault("byteorder", order)
        options.setdefault("real", real)
        super().__init__(**options)
        self.path = source.name

    def _publish_step(self) -> Callable[[], float]:
        """The recorded stream to the state client, restarted for each new one."""
        playing: Link | None = None

        def step() -> float:
            nonlocal playing
            links: list[Link] = self._state.links() if self._state else []
            if not links:
                if playing is not None:
                    playing = None
                    self.schedule.stop()
                return TICK_S
            now = time.monotonic()
            if playing not in links:
                playing = links[0]
                self.schedule.restart(now)
            frames = self.schedule.due(now)
            if frames and playing.send(b"".join(frames)):
                self.states_sent += len(frames)
            return TICK_S

        return step
