"""The Pioneer's commands in SI units, mixed into :class:`~robocli.devices.pioneer.Pioneer`:
motors, velocities clamped to the robot's limits, MOVE/HEAD/DHEAD, stops, accelerations,
sonar, odometry reset, digital and analog IO, tones, CONFIG and the simulator's pose. Motion
commands go out through :meth:`~robocli.devices.pioneer.keepalive.KeepAlive.command_motion`.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

from robocli.devices.pioneer import link
from robocli.errors import InvalidArgument, ProtocolError
from robocli.protocols import arcos
from robocli.protocols.arcos import Command
from robocli.robots.geometry import wrap_pi

if TYPE_CHECKING:
    from robocli.devices.pioneer.keepalive import KeepAlive
    from robocli.devices.pioneer.state import Odometry
    from robocli.devices.session import Session
    from robocli.robots.pioneer import RobotParams
    from robocli.transports import Transport

log = logging.getLogger("robocli.devices.pioneer")


class Commands:
    """Commands in SI units (see the module docstring)."""

    # provided by Pioneer
    _session: Session
    transport: Transport
    params: RobotParams
    config: dict[str, Any] | None
    _odo: Odometry
    _config_raw: bytes
    _clamp_warned: set[str]
    _keeper: KeepAlive

    def send_command(self, command: int, arg: int | str | bytes | None = None) -> None:
        """Send one raw ARCOS command (numbers in :class:`~robocli.protocols.arcos.Command`)."""
        self._session.send(arcos.encode_command(command, arg))

    def enable_motors(self) -> None:
        """Power the motors (ENABLE 1). A robot starts with them off, and ignores motion
        commands until they are on; the e-stop button also turns them off."""
        self.send_command(Command.ENABLE, 1)
        self._keeper.enable_sent = True

    def disable_motors(self) -> None:
        """Stop keeping set-points alive and power the motors off (ENABLE 0)."""
        self._keeper.set_setpoints([], moving=False)
        self._keeper.enable_sent = False
        self.send_command(Command.ENABLE, 0)

    def set_velocity(self, v: float, w: float = 0.0) -> None:
        """Translational (m/s) and rotational (rad/s, CCW +) velocity; re-sent by the
        keep-alive until changed. Like every motion command, raises :class:`WatchdogTripped`
        (and sends nothing) when it is the first one after the program stalled past the
        robot's watchdog.

        Values beyond the robot's limits (CONFIG's ``transvel_top``/``rotvel_top``, else the
        model's) are clamped to them with one warning, as the vendor SDK does: ``200`` is
        mm/s in the vendor's units but 200 m/s here. Raises
        :class:`~robocli.errors.InvalidArgument` for anything that is not a finite number.
        """
        v = self._limited("v", v, self.max_velocity, "m/s")
        w = self._limited("w", w, self.max_rot_velocity, "rad/s")
        vel = _clamp_int(round(v * 1000.0))
        rvel = _clamp_int(round(math.degrees(w)))
        self._keeper.command_motion([(Command.VEL, vel), (Command.RVEL, rvel)])

    @property
    def max_velocity(self) -> float:
        """The robot's top translational speed (m/s): CONFIG's ``transvel_top``, else the
        model's."""
        top = (self.config or {}).get("transvel_top")
        return top / 1000.0 if top else self.params.max_velocity

    @property
    def max_rot_velocity(self) -> float:
        """The robot's top rotational speed (rad/s): CONFIG's ``rotvel_top``, else the
        model's."""
        top = (self.config or {}).get("rotvel_top")
        return math.radians(top) if top else self.params.max_rot_velocity

    def _limited(self, name: str, value: float, limit: float, unit: str) -> float:
        value = _finite(name, value)
        if abs(value) <= limit:
            return value
        if name not in self._clamp_warned:
            self._clamp_warned.add(name)
            log.warning(
                "%s=%g %s is beyond the robot's limit of %g %s: clamped (robocli takes SI "
                "units; this warning is given once)", name, value, unit, limit, unit,
            )  # fmt: skip
        return math.copysign(limit, value)

    def set_wheel_velocities(self, left: float, right: float) -> None:
        """Independent wheel speeds (m/s) with VEL2, in steps of ``vel2_divisor`` mm/s."""
        div = self.params.vel2_divisor
        hi = max(-128, min(127, round(left * 1000.0 / div)))
        lo = max(-128, min(127, round(right * 1000.0 / div)))
        value = int.from_bytes(bytes((lo & 0xFF, hi & 0xFF)), "little", signed=True)
        self._keeper.command_motion([(Command.VEL2, value)])

    def move(self, distance: float) -> None:
        """Drive ``distance`` metres (negative: backwards) at the SETV speed, then stop."""
        self._keeper.command_motion([], (Command.MOVE, _clamp_int(round(distance * 1000.0))))

    def set_heading(self, th: float) -> None:
        """Turn to absolute odometry heading ``th`` (rad)."""
        deg = round(math.degrees(wrap_pi(th)))
        self._keeper.command_motion([], (Command.HEAD, deg))

    def turn(self, dth: float) -> None:
        """Turn by ``dth`` radians relative to the current heading (CCW +)."""
        self._keeper.command_motion([], (Command.DHEAD, _clamp_int(round(math.degrees(dth)))))

    def stop(self) -> None:
        """Stop translation and rotation with the normal deceleration (VEL 0 + RVEL 0,
        as the vendor SDK does; the zero set-points are kept alive)."""
        self._keeper.command_motion([(Command.VEL, 0), (Command.RVEL, 0)])

    def estop(self) -> None:
        """Emergency stop: maximum deceleration."""
        self._keeper.set_setpoints([(Command.VEL, 0), (Command.RVEL, 0)], moving=False)
        self.send_command(Command.ESTOP)

    def set_max_velocity(self, v: float | None = None, w: float | None = None) -> None:
        """Maximum translational (m/s, also MOVE speed) and rotational (rad/s) velocity."""
        if v is not None:
            self.send_command(Command.SETV, _clamp_int(round(abs(v) * 1000.0)))
        if w is not None:
            self.send_command(Command.SETRV, _clamp_int(round(math.degrees(abs(w)))))

    def set_acceleration(
        self,
        trans: float | None = None,
        rot: float | None = None,
        *,
        trans_decel: float | None = None,
        rot_decel: float | None = None,
    ) -> None:
        """Accelerations in m/s² and rad/s²; decelerations default to the accelerations."""
        for cmd, acc, dec in (
            (
                Command.SETA,
                trans,
                trans_decel,
            ),
            (Command.SETRA, rot, rot_decel),
        ):
            scale = 1000.0 if cmd == Command.SETA else math.degrees(1.0)
            if acc is not None:
                self.send_command(cmd, _clamp_int(round(abs(acc) * scale)))
            dec = acc if dec is None else dec
            if dec is not None:
                self.send_command(cmd, -_clamp_int(round(abs(dec) * scale)))

    def enable_sonar(self, on: bool = True) -> None:
        self.send_command(Command.SONAR, 1 if on else 0)

    def reset_odometry(self) -> None:
        """Zero the robot's odometry (SETO); the client pose restarts at (0, 0) at once,
        and follows the robot's counters again once it has applied the reset."""
        self.send_command(Command.SETO)
        with self._session.cond:
            self._odo.expect_reset(time.monotonic())

    def set_digital_out(self, mask: int, values: int) -> None:
        """Change the user digital outputs selected by ``mask`` to ``values``."""
        value = int.from_bytes(bytes((values & 0xFF, mask & 0xFF)), "little", signed=True)
        self.send_command(Command.DIGOUT, value)

    def select_analog(self, port: int) -> None:
        """Choose the analog port reported in every SIP (``state.analog``). Not on a
        simulator with a laser: there ADSEL's number (35) switches the laser."""
        self.send_command(Command.ADSEL, port)

    def request_io(self, mode: int = 1) -> None:
        """IO packets: 0 stop, 1 one, 2 continuous (decoded into :attr:`io`)."""
        self.send_command(Command.IOREQUEST, mode)

    def request_encoders(self, mode: int = 1) -> None:
        """Encoder packets: 0 stop, 1 one, 2 continuous (decoded into :attr:`encoders`)."""
        self.send_command(Command.ENCODER, mode)

    def say(self, tones: Iterable[tuple[float, int]]) -> None:
        """Play tones on the piezo: (duration s, tone 0..127) pairs, at most 20."""
        data = bytearray()
        for duration, tone in list(tones)[:20]:
            data += bytes((max(1, min(255, round(duration / 0.020))), tone & 0xFF))
        self.send_command(Command.SAY, bytes(data))

    def request_config(self, timeout: float = 1.0) -> dict[str, Any]:
        """Ask for a CONFIG packet and return its fields (raw units, as the robot sends).
        The caller reads the reply itself; raises :class:`TimeoutError` or the link's error,
        never returns an older CONFIG."""
        frame = self._session.request(link.CONFIG_REQUEST, link.is_config, timeout)
        if frame[3:-2] != self._config_raw:  # it did not decode (counted in decode_errors)
            raise ProtocolError(f"{self.transport.url}: the CONFIG reply did not decode")
        assert self.config is not None  # stored from this very frame by _on_frame
        return self.config


def _finite(name: str, value: object) -> float:
    """``value`` as a finite float, or :class:`InvalidArgument` naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InvalidArgument(f"{name} must be a number, not {value!r}")
    if not math.isfinite(value):
        raise InvalidArgument(f"{name} must be a finite number, not {value!r}")
    return float(value)


def _clamp_int(value: int) -> int:
    return max(-0x7FFF, min(0x7FFF, value))


__all__ = ["Commands"]
