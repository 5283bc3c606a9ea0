"""Hub sources from a Pioneer robot (or the built-in simulator) through the Pioneer client.

One ARCOS connection (:class:`PioneerLink`) is shared by the sources and opened when the
first of them starts. Samples follow the robot's SIPs (about 10 Hz), stamped with their
arrival on the hub's clock:

* ``battery`` (robocli's 0x22 record): the battery voltage and state of charge where the
  robot models it; ``UNDER_VOLTAGE`` below :data:`LOW_BATTERY_V`;
* ``adc``: channel 0 is the analog input selected on the robot (V), channels 1..7 its digital
  inputs 0..6 (0 or 5 V); DOUT_CTRL sets the robot's digital outputs 0..3.

Sonar and odometry have no ros4mat message; they are not served.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from robocli.errors import DeviceError
from robocli.hub_server.sources.base import Batch, Source, rate_param
from robocli.protocols.ros4mat import BatteryState, record_dtype
from robocli.transports import check_url

if TYPE_CHECKING:
    from robocli.devices.pioneer import Pioneer, PioneerState

__all__ = [
    "LOW_BATTERY_V",
    "PioneerAdcSource",
    "PioneerBatterySource",
    "PioneerLink",
]

LOW_BATTERY_V = 11.0


class PioneerLink:
    """The hub's one connection to a Pioneer at ``url``, opened by the first source that
    starts and closed when the last one stops."""

    def __init__(self, url: str) -> None:
        self.url = check_url(url, what="pioneer")  # malformed: refused; away: retried
        self._robot: Pioneer | None = None
        self._users = 0
        self._lock = threading.Lock()

    def acquire(self) -> Pioneer:
        """The connected robot (connecting now if needed)."""
        from robocli.devices.pioneer import Pioneer

        with self._lock:
            if self._robot is None or not self._robot.alive:
                self._robot = Pioneer.connect(self.url)
            self._users += 1
            return self._robot

    def release(self) -> None:
        with self._lock:
            self._users = max(0, self._users - 1)
            if self._users == 0 and self._robot is not None:
                self._robot.close()
                self._robot = None

    @property
    def robot(self) -> Pioneer:
        robot = self._robot
        if robot is None:
            raise DeviceError(f"the Pioneer at {self.url} is not connected")
        return robot


class _SipSource(Source):
    """A source sampling each new SIP of the shared robot."""

    simulated = False
    RECORD = ""

    def __init__(self, link: PioneerLink) -> None:
        self.link = link
        self._last_sip = -1
        self._started = False
        super().__init__()

    def configure(self, params: Mapping[str, Any]) -> None:
        self.rate = rate_param(params, "freq_acquisition", 10.0, 1000.0)  # the SIP rate rules
        self.batch_rate = 20.0
        self.params = {"pioneer": self.link.url}

    def dtype(self) -> np.dtype[Any]:
        return record_dtype(self.RECORD)

    def start(self, t0: float) -> None:
        if not self._started:
            self.link.acquire()
            self._started = True

    def stop(self) -> None:
        if self._started:
            self._started = False
            self.link.release()

    def poll(self, now: float) -> Batch:
        state = self.link.robot.state
        if state.sip_count == self._last_sip:
            return self.empty()
        self._last_sip = state.sip_count
        t = np.array([state.t + (self.clock() - time.monotonic())])
        rec = np.zeros(1, dtype=self.dtype())
        rec["t"] = t
        self.fill(rec[0], state)
        return t, rec

    def fill(self, rec: Any, state: PioneerState) -> None:
        raise NotImplementedError


class PioneerBatterySource(_SipSource):
    """The robot's battery (voltage, state of charge)."""

    name = "battery"
    RECORD = "battery"

    def fill(self, rec: Any, state: PioneerState) -> None:
        rec["vtotal"] = state.battery
        rec["current"] = math.nan
        soc = state.state_of_charge
        rec["state_of_charge"] = math.nan if soc is None else soc
        rec["state"] = BatteryState.UNDER_VOLTAGE if state.battery < LOW_BATTERY_V else 0


class PioneerAdcSource(_SipSource):
    """The robot's analog input (channel 0) and digital inputs 0..6 (channels 1..7)."""

    name = "adc"
    RECORD = "adc"

    def __init__(self, link: PioneerLink) -> None:
        self._digital = [0, 0, 0, 0]
        super().__init__(link)

    def fill(self, rec: Any, state: PioneerState) -> None:
        rec["channels"] = [state.analog] + [5.0 * (state.digin >> k & 1) for k in range(7)]

    @property
    def digital(self) -> list[int]:
        """The digital outputs 0..3 last set through DOUT_CTRL."""
        return list(self._digital)

    @digital.setter
    def digital(self, levels: list[int]) -> None:
        bits = sum(1 << k for k, v in enumerate(levels) if v)
        self.link.robot.set_digital_out(0x0F, bits)
        self._digital = [1 if v else 0 for v in levels]

    def settings(self) -> dict[str, Any]:
        return {**super().settings(), "digital_out": self.digital}
