"""A Pioneer on Zenoh: its state out to any number of watchers, velocity in from one
controller at a time (:class:`~robocli.bridge.control.ControlGate`).

Keys (``<robot>`` is the bridge's name; see :mod:`robocli.zenoh.robot_keys`):

* ``robocli/<robot>/state``, one put per SIP: ``t`` (epoch s, when the bridge received
  it), ``x``, ``y`` (m), ``th`` (rad), ``v`` (m/s), ``w`` (rad/s, CCW +),
  ``left_velocity``, ``right_velocity`` (m/s), ``battery`` (V), ``state_of_charge``
  (0..1 or null), ``motors_enabled``, ``estop``, ``stall_left``, ``stall_right``,
  ``bumpers_front``, ``bumpers_rear`` (bit masks), ``sonar`` (m per sonar, null before a
  reading), ``digin``, ``digout``, ``analog`` (V), ``temperature`` (deg C or null),
  ``sip_count``, ``holder`` (who drives it, or null);
* ``robocli/<robot>/laser``, one put per scan: ``t``, ``pose`` (``x``, ``y`` m, ``th`` rad,
  odometry at the scan), ``angles`` (rad), ``ranges`` (m, null: no return);
* ``robocli/<robot>/@control/<holder>/velocity``, put by the holder: ``{"v": m/s, "w":
  rad/s, "epoch": N}``, re-sent at least every 0.5 s while the robot should move; values
  beyond the robot's limits are clamped to them. Who sends is the key's ``<holder>`` chunk; a
  moving command older than the last stop the bridge made is ignored (``epoch``: see
  :mod:`robocli.bridge.control`).

The Pioneer client keeps its own keep-alive and watchdog logic: if the bridge stalls past
the robot's watchdog, the robot is stopped and the trip is a fault put on the event key; the
bridge then ignores motion commands until the holder sends a stop (``v`` = ``w`` = 0).
"""

from __future__ import annotations

import logging
import math
import threading
from typing import TYPE_CHECKING, Any

from robocli.bridge.base import Bridge
from robocli.bridge.control import DEFAULT_SILENCE_S, DEFAULT_TOKEN_WAIT_S, ControlGate
from robocli.devices.pioneer import Pioneer, PioneerState, WatchdogTrip, WatchdogTripped
from robocli.errors import ProtocolError, RobocliError
from robocli.zenoh.keys import alive_key, info_key, topic_key
from robocli.zenoh.robot_keys import (
    JSON_ENCODING,
    decode,
    holder_key,
    holder_of,
    number,
    put,
)

if TYPE_CHECKING:
    import zenoh

log = logging.getLogger("robocli.bridge")


def state_json(state: PioneerState, n_sonar: int, offset: float) -> dict[str, Any]:
    """``state`` as the JSON of ``robocli/<robot>/state`` (``offset``: epoch - monotonic)."""
    data = {k: getattr(state, k) for k in state.__dataclass_fields__}
    data["t"] = state.t + offset
    del data["sonar_time"]
    data["sonar"] = [None if math.isnan(r) else r for r in state.sonar[:n_sonar]]
    return data


class PioneerBridge(Bridge):
    """Put ``robot`` on ``session`` as ``name`` until :meth:`close` (see the module).

    ``silence``: seconds without a command after which a moving robot is stopped (None: only
    the holder's liveliness and the bridge's end stop it); ``token_wait``: seconds a new
    holder has to declare its liveliness token. The bridge does not own ``robot`` or
    ``session``: close them after it."""

    device = "robot"

    def __init__(self, robot: Pioneer, session: zenoh.Session, name: str, *,
                 silence: float | None = DEFAULT_SILENCE_S,
                 token_wait: float = DEFAULT_TOKEN_WAIT_S) -> None:  # fmt: skip
        super().__init__(name)
        self.robot = robot
        # a stall (the trip): motion refused until the holder stops; then that trip is
        # acknowledged, and the Pioneer's refusal of the next motion command for it is spent
        self._latched: WatchdogTrip | None = None
        self._acknowledged: WatchdogTrip | None = None
        self._bad_commands = 0
        z = session
        self.gate = ControlGate(z, self.name, stop=self._stop, grant=self._grant,
                                silence=silence, token_wait=token_wait)  # fmt: skip
        self._state = z.declare_publisher(topic_key(self.name, "state"), encoding=JSON_ENCODING)
        self._laser = z.declare_publisher(topic_key(self.name, "laser"), encoding=JSON_ENCODING)
        self._velocity = z.declare_subscriber(holder_key(self.name, None, "velocity"),
                                              self._on_velocity)  # fmt: skip
        self._info = z.declare_queryable(info_key(self.name), self._on_info)
        robot.add_listener(self._on_trip, kind="watchdog")
        self._threads = [threading.Thread(target=self._publish, daemon=True,
                                          name=f"bridge-pioneer-{self.name}")]  # fmt: skip
        self._threads[0].start()
        self._alive = z.liveliness().declare_token(alive_key(self.name, "pioneer"))
        self._inbound = (self._velocity, self._alive)
        self._outbound = (self._info, self._state, self._laser)

    # ------------------------------------------------------------------ serving

    def info(self) -> dict[str, Any]:
        """What ``robocli/<robot>/@info`` answers."""
        r = self.robot
        return {
            "name": self.name, "kind": "pioneer",
            "identity": {"name": r.identity.name, "type": r.identity.type,
                         "subtype": r.identity.subtype},
            "subtype": r.params.subtype, "url": r.transport.url,
            "max_velocity": r.max_velocity, "max_rot_velocity": r.max_rot_velocity,
            "sonar": len(r.params.sonar), "simulator": r.is_simulator,
            "holder": self.gate.holder, "silence": self.gate.silence,
            "keys": self._keys(("state", "laser"), "velocity"),
        }  # fmt: skip

    def _publish(self) -> None:
        """Put every SIP's state (and each new laser scan) until closed or the link fails."""
        robot, n_sonar, last_scan = self.robot, len(self.robot.params.sonar), -math.inf

        def put_one(state: PioneerState) -> None:
            nonlocal last_scan
            data = state_json(state, n_sonar, self._offset)
            data["holder"] = self.gate.holder
            put(self._state, data)
            scan = robot.sim.laser if robot.sim is not None else None
            if scan is not None and scan.t > last_scan:
                last_scan = scan.t
                put(self._laser, {
                    "t": scan.t + self._offset,
                    "pose": dict(zip(("x", "y", "th"), scan.pose, strict=True)),
                    "angles": list(scan.angles),
                    "ranges": [None if math.isinf(r) else r for r in scan.ranges],
                })  # fmt: skip

        self._put_each(lambda timeout: robot.wait_for_sip(timeout=timeout), lambda: robot.alive,
                       put_one)  # fmt: skip

    def _check_link(self) -> str:
        self.robot.state  # noqa: B018 - raises the error that ended the link
        return f"{self.robot.transport.url}: no SIP"

    # ------------------------------------------------------------------ commands

    def _on_velocity(self, sample: zenoh.Sample) -> None:
        what = f"{self.name} velocity command"
        try:
            holder = holder_of(sample.key_expr, self.name, "velocity")
            data = decode(sample.payload.to_bytes(), what)
            v = number(data, "v", what)
            w = number(data, "w", what) if "w" in data else 0.0
            epoch = data.get("epoch")
            if epoch is not None and (isinstance(epoch, bool) or not isinstance(epoch, int)):
                raise ProtocolError(f"{what}: 'epoch' must be an integer, not {epoch!r}")
        except ProtocolError as exc:
            self._bad_commands += 1
            if self._bad_commands == 1:
                log.warning("%s (later ones only counted)", exc)
                self.gate.event("ignored", holder=self.gate.holder, reason=str(exc))
            return
        self.drive(holder, v, w, epoch)

    def drive(self, holder: str, v: float, w: float, epoch: int | None = None) -> None:
        """One velocity command of ``holder`` (m/s, rad/s; ``epoch``: the one it carries),
        under the gate's rules: ignored unless ``holder`` holds the robot and the command is
        fresh, and no motion after a stall until a stop (see the module)."""
        moving = v != 0.0 or w != 0.0
        with self.gate.command(holder, moving, epoch) as ok:
            if not ok:
                return
            if self._latched is not None:
                if moving:
                    return  # a fault: the holder stops before the robot moves again
                self._acknowledged, self._latched = self._latched, None
            try:
                try:
                    self.robot.set_velocity(v, w)
                except WatchdogTripped as exc:
                    if exc.trip != self._acknowledged:
                        self._latch(exc.trip)
                        return
                    self.robot.set_velocity(v, w)  # that trip was reported and stopped for
            except RobocliError as exc:
                self.gate.event("fault", holder=self.gate.holder, reason=str(exc))

    def _on_trip(self, trip: WatchdogTrip) -> None:
        self._latch(trip)

    def _latch(self, trip: WatchdogTrip) -> None:
        """A stall: the robot was stopped by its watchdog. Motion is refused until a stop."""
        if self._latched is None and trip != self._acknowledged:
            self._latched = trip
            self.gate.fault(  # a new epoch: set-points from before the stall are stale
                f"the bridge sent nothing for {trip.silence:.1f} s, past the robot's "
                f"{trip.watchdog:g} s watchdog: the robot was stopped; send a stop (v=w=0) "
                "before moving again"
            )

    def _grant(self, holder: str) -> None:
        if self._latched is not None:  # a new holder starts from a stopped robot
            self._acknowledged, self._latched = self._latched, None
        self.robot.enable_motors()

    def _stop(self, reason: str) -> None:
        self.robot.stop()


__all__ = ["PioneerBridge", "state_json"]
