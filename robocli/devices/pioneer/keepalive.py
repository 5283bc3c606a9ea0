"""What keeps a commanded Pioneer safe and alive, mixed into
:class:`~robocli.devices.pioneer.Pioneer`: the set-points the keep-alive re-sends (PULSE
when there are none), the watchdog trip of a program that stalled (:class:`WatchdogTrip`,
:class:`WatchdogTripped`, ``robot.add_listener(f, kind="watchdog")``), the dead-man and the SIP
supervisor. Every motion command goes out through :meth:`KeepAlive.command_motion`.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

from robocli.devices.listeners import Listeners
from robocli.devices.pioneer import link
from robocli.devices.pioneer.state import sip_motors_on
from robocli.errors import EXIT_FAILURE, RobocliError, TimeoutError
from robocli.protocols import arcos
from robocli.protocols.arcos import Command

if TYPE_CHECKING:
    from robocli.devices.pioneer.link import PioneerStats
    from robocli.devices.session import PeriodicTask, Session
    from robocli.transports import Transport

log = logging.getLogger("robocli.devices.pioneer")

_PULSE = arcos.encode_command(Command.PULSE)
#: The robot's watchdog (s) when its CONFIG does not say (ARCOS' and the simulators' default).
DEFAULT_WATCHDOG_S = 2.0
#: Commands that make the robot move (dropped when they would go out after a stall).
_MOTION_COMMANDS = frozenset(
    int(c) for c in (Command.VEL, Command.RVEL, Command.VEL2, Command.ROTATE, Command.MOVE,
                     Command.HEAD, Command.DHEAD, Command.DCHEAD)
)  # fmt: skip
#: The motion commands that stop the robot (always let through).
_STOPS = frozenset(arcos.encode_command(c, 0) for c in (Command.VEL, Command.RVEL, Command.VEL2))


def _moves(packet: bytes) -> bool:
    return packet[3] in _MOTION_COMMANDS and packet not in _STOPS


@dataclass(frozen=True)
class WatchdogTrip:
    """The program stalled past the robot's watchdog while the robot was commanded to move.

    ``t``: monotonic time the client found it (the first packet after the stall);
    ``silence``: seconds during which nothing went out; ``watchdog``: the robot's (s)."""

    t: float
    silence: float
    watchdog: float


#: Watchdog-trip listener signature: called with each trip, in the thread that found it.
WatchdogListener = Callable[[WatchdogTrip], None]


class WatchdogTripped(RobocliError):
    """Raised by the first motion command after a :class:`WatchdogTrip`: the program stalled,
    the robot's watchdog stopped it and the client cleared the set-points. The command is
    not sent; the next one moves the robot again."""

    exit_code = EXIT_FAILURE

    def __init__(self, message: str, trip: WatchdogTrip) -> None:
        super().__init__(message)
        self.trip = trip


class _Robot(Protocol):
    """What :class:`KeepAlive` uses of the Pioneer it belongs to."""

    _session: Session
    transport: Transport
    stats: PioneerStats
    sip_timeout: float
    keepalive: float
    deadman: float | None
    watchdog: float
    _sip: tuple[bytes, float, tuple[int, int]] | None
    _last_sip: float

    def stop(self) -> None: ...


class KeepAlive:
    """Set-points kept alive, watchdog trips, dead-man and SIP supervision (see the module
    docstring): a part of the :class:`~robocli.devices.pioneer.Pioneer` it is made by,
    holding the set-points and the trip state; the robot's commands go through
    :meth:`command_motion` and :meth:`set_setpoints`, its session calls
    :meth:`before_send`, :meth:`on_sent`, :meth:`keepalive_step` and
    :meth:`supervise_step`."""

    def __init__(self, robot: _Robot) -> None:
        self._robot = robot
        self._session = robot._session
        self.last_app_command = time.monotonic()
        # set-points re-sent by the keep-alive: list of (command, arg) in send order
        self._setpoints: list[tuple[int, int]] = []
        self._setpoint_lock = threading.Lock()
        # the last motion command asked the robot to move (cleared by a stop or a trip)
        self._motion_commanded = False
        self._trip_pending: WatchdogTrip | None = None  # for the next motion command
        self._trip_unannounced: WatchdogTrip | None = None  # for the listeners
        #: the watchdog trips' listeners (``robot.add_listener(f, kind="watchdog")``)
        self.listeners: Listeners[WatchdogListener] = Listeners(
            robot.stats, "pioneer watchdog trip"
        )
        self._motors_off_warned = False
        self.enable_sent = False  # ENABLE 1 went out (the next SIPs may not show it yet)
        self.supervisor: PeriodicTask | None = None  # the session's task of supervise_step

    def _judge_silence(self) -> None:
        """Before a command that changes the set-points: after a silence longer than the
        watchdog, a PULSE first, so that a trip is judged on what the robot was doing
        during the silence, not on what the command asks."""
        if time.monotonic() - self._session.last_tx > self._robot.watchdog:
            self._session.send(_PULSE)

    def set_setpoints(self, setpoints: list[tuple[int, int]], moving: bool) -> None:
        self._judge_silence()
        with self._setpoint_lock:
            self._setpoints = setpoints
            self._motion_commanded = moving

    def command_motion(
        self, setpoints: list[tuple[int, int]], once: tuple[int, int] | None = None
    ) -> None:
        """Send motion commands now; ``setpoints`` are then kept alive, ``once`` is not.
        The first command that would move the robot after a watchdog trip raises instead."""
        session = self._session
        session.check()
        moving = once is not None or any(arg != 0 for _, arg in setpoints)
        self._judge_silence()
        with self._setpoint_lock:
            trip = self._trip_pending
            if moving and trip is not None:
                self._trip_pending = None
            else:
                trip = None
                self._setpoints = setpoints
                self._motion_commanded = moving
        if trip is not None:
            raise WatchdogTripped(
                f"{self._robot.transport.url}: this program sent nothing for {trip.silence:.1f} s, "
                f"past the robot's {trip.watchdog:g} s watchdog (it was stopped, suspended or "
                "paused): the robot was stopped and its set-points cleared; this command was "
                "not sent, the next one moves the robot again",
                trip,
            )
        self.last_app_command = time.monotonic()
        if not (self._motors_off_warned or self.enable_sent or self._motors_on()):
            self._motors_off_warned = True
            log.warning(
                "%s: the motors are disabled, so the robot will not move: call "
                "enable_motors() first (state.motors_enabled tells; warned once)",
                self._robot.transport.url,
            )
        packets = [arcos.encode_command(cmd, arg) for cmd, arg in setpoints]
        if once is not None:
            packets.append(arcos.encode_command(*once))
        session.send_many(packets)  # one write: a stall cannot fall between them
        if self._robot.deadman is not None:
            if self.supervisor is not None:
                self.supervisor.wake()

    def _motors_on(self) -> bool:
        """The motors flag of the latest SIP (no decode: one byte of the body)."""
        sip = self._robot._sip
        if sip is None:
            return True
        return sip_motors_on(sip[0])

    def keepalive_step(self) -> float:
        """Re-send the set-points (PULSE when there are none) once nothing was sent for
        ``keepalive`` s; sleep until then."""
        now = time.monotonic()
        due = self._session.last_tx + self._robot.keepalive
        if now < due:
            return due - now
        with self._setpoint_lock:
            setpoints = list(self._setpoints)
        self._robot.stats.add("keepalives")
        self._robot.stats.keepalive_times.append(now)
        if setpoints:  # one write: after a stall, _before_send replaces all of them
            self._session.send_many([arcos.encode_command(cmd, arg) for cmd, arg in setpoints])
        else:
            self._session.send(_PULSE)
        return self._robot.keepalive

    def before_send(self, packets: Sequence[bytes], silence: float) -> Sequence[bytes]:
        """Every write, right before it goes out (and right after it, with no packets:
        see :meth:`Session._send`): after ``silence`` s without a packet, longer than the
        watchdog, while the robot was commanded to move, the program stalled and the
        robot's watchdog has stopped it. Clear the set-points, note the trip for the next
        motion command and the listeners, and write a stop in place of any motion command
        (the keep-alive's stale set-points). Once the set-points were cleared (a trip, a
        stop), a packet that would move the robot was decided before that and waited for
        the write (behind a stalled writer): it is dropped."""
        if not self._motion_commanded:
            if any(_moves(p) for p in packets):
                return [p for p in packets if not _moves(p)]
            return packets
        if silence <= self._robot.watchdog:
            return packets
        with self._setpoint_lock:
            if not self._motion_commanded:  # another thread found it first
                return packets
            trip = WatchdogTrip(time.monotonic(), silence, self._robot.watchdog)
            self._setpoints = []
            self._motion_commanded = False
            self._trip_pending = self._trip_unannounced = trip
        self._robot.stats.add("watchdog_trips")
        log.warning(
            "%s: nothing was sent for %.1f s, past the robot's %g s watchdog (this program "
            "stalled): the robot was stopped; set-points cleared, it moves again only on a "
            "new command", self._robot.transport.url, silence, self._robot.watchdog,
        )  # fmt: skip
        kept = [p for p in packets if not _moves(p)]
        return [*link.EMERGENCY_STOP, *kept]

    def on_sent(self, now: float) -> None:
        """After each packet written: its time; a watchdog trip to announce."""
        self._robot.stats.tx_times.append(now)
        if self._trip_unannounced is not None:
            with self._setpoint_lock:
                trip, self._trip_unannounced = self._trip_unannounced, None
            if trip is not None:
                self.listeners.notify(trip)

    def silence_error(self) -> TimeoutError:
        """What a robot silent for ``sip_timeout`` is said to be, whoever notices first."""
        return TimeoutError(
            f"{self._robot.transport.url}: no SIP for {self._robot.sip_timeout:g} s "
            "(robot off, cable unplugged, or session closed)"
        )

    def supervise_step(self) -> float:
        """No SIP for ``sip_timeout``: fail (the session stops the robot). With a dead-man:
        stop a moving robot ``deadman`` s after the last motion command."""
        now = time.monotonic()
        silent_at = self._robot._last_sip + self._robot.sip_timeout
        if now > silent_at:
            self._session.fail(self.silence_error())
            return self._robot.sip_timeout
        wait = silent_at - now
        if self._robot.deadman is not None:
            with self._setpoint_lock:
                moving = any(arg != 0 for _, arg in self._setpoints)
            due = self.last_app_command + self._robot.deadman
            if moving and now >= due:
                log.warning("dead-man: no motion command for %.2f s, stopping", now - due
                            + self._robot.deadman)  # fmt: skip
                self._robot.stats.add("deadman_stops")
                self._robot.stop()
            elif moving:
                wait = min(wait, due - now)
        return max(0.001, wait)


__all__ = ["KeepAlive", "WatchdogListener", "WatchdogTrip", "WatchdogTripped"]
