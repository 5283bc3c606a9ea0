"""Every frame a Pioneer sends, decoded into the client's state, mixed into
:class:`~robocli.devices.pioneer.Pioneer`: SIPs (odometry and sonar at once, the
:class:`~robocli.devices.pioneer.state.PioneerState` when the program asks), CONFIG, IO,
encoder and battery packets; laser packets go on to
:class:`~robocli.devices.pioneer.simulated.PioneerSimulator`. Runs in the reader thread or
in a caller reading its own reply.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any

from robocli.devices.pioneer import link
from robocli.devices.pioneer.state import (
    PioneerState,
    build_state,
    sip_essentials,
    sip_state_of_charge,
)
from robocli.errors import TimeoutError
from robocli.protocols import arcos
from robocli.protocols.arcos import PacketType

if TYPE_CHECKING:
    from robocli.devices.pioneer.link import PioneerStats
    from robocli.devices.pioneer.state import Odometry
    from robocli.devices.session import Session
    from robocli.robots.pioneer import RobotParams
    from robocli.transports import Transport


class Decoding:
    """Received frames into the client's state (see the module docstring)."""

    # provided by Pioneer
    _session: Session
    transport: Transport
    stats: PioneerStats
    params: RobotParams
    config: dict[str, Any] | None
    io: dict[str, Any] | None
    encoders: tuple[int, int] | None
    battery_info: dict[str, Any] | None
    _odo: Odometry
    _sonar: list[float]
    _sonar_t: list[float]
    _state: PioneerState | None
    _sip: tuple[bytes, float, tuple[int, int]] | None
    _config_raw: bytes
    _last_sip: float
    _soc_seen: bool

    if TYPE_CHECKING:

        def _on_laser(self, ptype: int, body: bytes, now: float) -> None: ...

    def _on_frame(self, frame: bytes, now: float) -> None:
        """Every received frame, in the reader thread or a caller waiting for a reply."""
        ptype = frame[3]
        if ptype & 0xF0 == 0x30:
            start = time.thread_time()
            self._on_sip(frame, now)
            self.stats.sip_work.append(time.thread_time() - start)
        elif ptype == PacketType.CONFIG:
            self._store_config(link.payload_of(frame))
        elif ptype == PacketType.IO:
            self.io = link.parse_body(arcos.IO, link.payload_of(frame), "IO")
        elif ptype == PacketType.ENCODER:
            enc = link.parse_body(arcos.ENCODER, link.payload_of(frame), "ENCODER")
            self.encoders = (int(enc["left"]), int(enc["right"]))
        elif ptype == PacketType.BATTERY:
            self.battery_info = link.parse_body(arcos.BATTERY, link.payload_of(frame), "BATTERY")
        elif ptype in (PacketType.SIM_LASER, PacketType.SIM_LASER_A):
            self._on_laser(ptype, frame[4:-2], now)

    def _store_config(self, payload: bytes) -> None:
        if payload != self._config_raw:  # construct is slow; CONFIG rarely changes
            self.config = dict(link.parse_body(arcos.CONFIG, payload, "CONFIG"))
            self._config_raw = payload

    def _on_sip(self, frame: bytes, now: float) -> None:
        # The per-SIP work is kept to the odometry counters and the sonar readings; the rest
        # of the SIP is decoded, and the SI-unit state built, when the program asks for it.
        body = frame[4:-2]
        x, y, readings = sip_essentials(body)
        # A charge of 0 reads "not modelled" until the robot has shown another value, in any
        # SIP: the state is built lazily, so a SIP nobody read must still count.
        if not self._soc_seen and sip_state_of_charge(body):
            self._soc_seen = True
        conv = self.params.range_conv / 1000.0
        sonar, sonar_t = self._sonar, self._sonar_t
        n_sonar = len(sonar)
        cond = self._session.cond
        with cond:
            for number, rng in readings:
                if number < n_sonar:
                    sonar[number] = rng * conv
                    sonar_t[number] = now
            self._sip = (body, now, self._odo.update(x, y, now))
            self.stats.sips += 1
            self.stats.sip_times.append(now)
            self._state = None
            self._last_sip = now
            cond.notify_all()

    def _current_state(self) -> PioneerState:
        """The latest SIP as a :class:`PioneerState` (built once per SIP; hold the cond)."""
        if self._state is None:
            if self._sip is None:
                raise TimeoutError(f"{self.transport.url}: no SIP received yet")
            body, now, odo = self._sip
            sip = arcos.decode_sip(body)
            self._state = build_state(
                sip, now, odo, tuple(self._sonar), tuple(self._sonar_t),
                self.params, self.stats.sips, soc_seen=self._soc_seen,
            )  # fmt: skip
        return self._state


__all__ = ["Decoding"]
