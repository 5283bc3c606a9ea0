"""What the simulated mobile robots share in front of their controller: :class:`RobotFront`.

The Pioneer and the Create simulators each serve one client at a time on a TCP port, a
pseudo-terminal or both, stream from a ticker once anything is served, and close every
server and thread, bounded and idempotent. Only the server each one builds (its protocol,
framer, limits) and what its tick sends differ.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from robocli.closing import Closing
from robocli.errors import TransportError
from robocli.serving.server import Server
from robocli.serving.ticker import Ticker

__all__ = ["PoseTruth", "RobotFront"]


@dataclass(frozen=True)
class PoseTruth:
    """What every mobile robot's snapshot begins with: ``x, y, th``, the true pose in the
    world (m, rad), and ``odom_*``, the robot's own odometry (m, rad)."""

    x: float
    y: float
    th: float
    odom_x: float
    odom_y: float
    odom_th: float


class RobotFront(Closing):
    """Base of a simulator served on ``"tcp"`` and/or ``"pty"``: subclasses build the
    :class:`~robocli.serving.server.Server` for a kind (:meth:`_new_server`) and send from
    :meth:`_tick`, called every ``period`` wall seconds once anything is served."""

    def __init__(self, period: float, ticker_name: str) -> None:
        self._ticker = Ticker(period, self._tick, ticker_name)
        self._servers: dict[str, Server] = {}
        self._closed = False

    @property
    def url(self) -> str | None:
        """``tcp://host:port`` once :meth:`serve_tcp` ran."""
        return self._servers["tcp"].url if "tcp" in self._servers else None

    @property
    def pty_path(self) -> str | None:
        """The pseudo-terminal device once :meth:`serve_pty` ran."""
        return self._servers["pty"].pty_path if "pty" in self._servers else None

    def close(self) -> None:
        """Stop every thread and close every socket/fd (bounded in time). Idempotent."""
        if self._closed:
            return
        self._closed = True
        self._ticker.close()
        for server in self._servers.values():
            server.close()

    def _serving(self) -> list[Server]:
        return list(self._servers.values())

    def _serve(self, kind: str, start: Callable[[Server], str]) -> str:
        """Build the ``kind`` server, start it with ``start`` (closed again if that fails) and
        the ticker; what ``start`` returns (a URL or a device path)."""
        if self._closed:
            raise TransportError("simulator is closed")
        if kind in self._servers:
            where = self.url if kind == "tcp" else self.pty_path
            raise TransportError(f"already serving on {where}")
        server = self._new_server(kind)
        try:
            where = start(server)
        except BaseException:
            server.close()
            raise
        self._servers[kind] = server
        self._ticker.start()
        return where

    def _new_server(self, kind: str) -> Server:
        raise NotImplementedError

    def _tick(self, now: float) -> None:
        raise NotImplementedError
