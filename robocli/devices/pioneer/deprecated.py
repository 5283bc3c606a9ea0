"""The Pioneer's old names, kept for one release: each warns once (a one-line
:class:`DeprecationWarning` naming its new spelling) and does what the new one does.
Delete this module, and its base in :class:`~robocli.devices.pioneer.Pioneer`, in the
release after."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from robocli.devices.base import deprecated
from robocli.devices.pioneer.keepalive import WatchdogListener
from robocli.devices.pioneer.laser import LaserScan, SimStatus
from robocli.devices.pioneer.simulated import LaserListener, PioneerSimulator

if TYPE_CHECKING:
    from collections.abc import Callable

    from robocli.devices.base import ListenerHandle
    from robocli.devices.session import Session


class DeprecatedNames:
    """``robot.start_laser()`` -> ``robot.sim.start_laser()``, ``robot.on_laser(f)`` ->
    ``robot.add_listener(f, kind="laser")``, ``robot.connected`` -> ``robot.alive``..."""

    _simulated: PioneerSimulator
    _session: Session

    if TYPE_CHECKING:

        def add_listener(
            self, listener: Callable[..., None], *, kind: str = "frames"
        ) -> ListenerHandle: ...

        def remove_listener(
            self, listener: Callable[..., None], *, kind: str = "frames"
        ) -> None: ...

    @property
    def connected(self) -> bool:
        """Deprecated: ``alive``."""
        deprecated("Pioneer.connected", "Pioneer.alive")
        return self._session.alive

    def on_watchdog_trip(self, listener: WatchdogListener) -> None:
        """Deprecated: ``add_listener(listener, kind="watchdog")``."""
        deprecated("Pioneer.on_watchdog_trip", 'Pioneer.add_listener(..., kind="watchdog")')
        self.add_listener(listener, kind="watchdog")

    def remove_watchdog_trip_listener(self, listener: WatchdogListener) -> None:
        """Deprecated: ``remove_listener(listener, kind="watchdog")``."""
        deprecated("Pioneer.remove_watchdog_trip_listener",
                   'Pioneer.remove_listener(..., kind="watchdog")')  # fmt: skip
        self.remove_listener(listener, kind="watchdog")

    def on_laser(self, listener: LaserListener) -> None:
        """Deprecated: ``add_listener(listener, kind="laser")``."""
        deprecated("Pioneer.on_laser", 'Pioneer.add_listener(..., kind="laser")')
        self.add_listener(listener, kind="laser")

    def remove_laser_listener(self, listener: LaserListener) -> None:
        """Deprecated: ``remove_listener(listener, kind="laser")``."""
        deprecated("Pioneer.remove_laser_listener", 'Pioneer.remove_listener(..., kind="laser")')
        self.remove_listener(listener, kind="laser")

    @property
    def laser(self) -> LaserScan | None:
        """Deprecated: ``sim.laser``."""
        deprecated("Pioneer.laser", "Pioneer.sim.laser")
        return self._simulated.laser

    def start_laser(
        self, start: float = -math.pi / 2, end: float = math.pi / 2,
        resolution: float = math.radians(1.0), *, extended: bool = True,
        max_range: float = 32.0, new_commands: bool = False,
    ) -> None:  # fmt: skip
        """Deprecated: ``sim.start_laser(...)``."""
        deprecated("Pioneer.start_laser", "Pioneer.sim.start_laser")
        self._simulated.start_laser(start, end, resolution, extended=extended,
                                    max_range=max_range, new_commands=new_commands)  # fmt: skip

    def stop_laser(self, *, new_commands: bool = False) -> None:
        """Deprecated: ``sim.stop_laser()``."""
        deprecated("Pioneer.stop_laser", "Pioneer.sim.stop_laser")
        self._simulated.stop_laser(new_commands=new_commands)

    def wait_for_laser(self, timeout: float | None = None) -> LaserScan:
        """Deprecated: ``sim.wait_for_laser(...)``."""
        deprecated("Pioneer.wait_for_laser", "Pioneer.sim.wait_for_laser")
        return self._simulated.wait_for_laser(timeout)

    def sim_status(self, timeout: float = 2.0) -> SimStatus:
        """Deprecated: ``sim.status(...)``."""
        deprecated("Pioneer.sim_status", "Pioneer.sim.status")
        return self._simulated.status(timeout)

    def set_simulator_pose(self, x: float, y: float, th: float) -> None:
        """Deprecated: ``sim.set_pose(...)``."""
        deprecated("Pioneer.set_simulator_pose", "Pioneer.sim.set_pose")
        self._simulated.set_pose(x, y, th)
