"""The ARCOS side of the simulated Pioneer: what its microcontroller does, without sockets.

:class:`ArcosController` is the robot's firmware: the handshake state machine, the command
handlers driving a :class:`~robocli.sim.pioneer.model.PioneerModel`, the server packets (SIP,
CONFIG, IO, encoder, battery; built in :mod:`robocli.sim.pioneer.packets`), the watchdog, and
the rule that one client at a time holds the session. :class:`ArcosSession` is one link's
protocol state (a :class:`~robocli.serving.server.ServerSession`): the serving layer hands it
complete frames from the link's thread and writes its replies; the simulator's ticker calls
:meth:`ArcosController.tick` and pushes the packets it returns. Every method that touches state
takes the controller's lock.

Deliberate differences from MobileSim/AMRISim are listed in ``robocli.sim.pioneer.server``.
"""

from __future__ import annotations

import collections
import logging
import math
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

from construct import ConstructError

from robocli.errors import RobocliError
from robocli.protocols.arcos import (
    MAX_PAYLOAD,
    Command,
    DecodedCommand,
    PacketType,
    decode_command,
    encode_server,
    encode_sip_body,
    frame,
    split_two_bytes,
)
from robocli.serving.server import Link
from robocli.sim.laser import LaserSpec
from robocli.sim.pioneer.model import PioneerModel, clamp
from robocli.sim.pioneer.packets import ServerPackets
from robocli.sim.pioneer.simext import Georef, SimExtensions

__all__ = ["ArcosController", "ArcosSession"]

log = logging.getLogger("robocli.sim.pioneer.server")

HANDSHAKE_TIMEOUT_S = 10.0  #: wall seconds of silence after which a half-open handshake resets

# ArcosSession.sync_state values
PRE_SYNC, AFTER_SYNC0, AFTER_SYNC1, AFTER_SYNC2, IN_SESSION = 0, 1, 2, 3, 4


class ArcosSession:
    """One link's ARCOS state: handshake progress, watchdog, packet requests."""

    def __init__(self, controller: ArcosController, link: Link, now: float) -> None:
        self.controller, self.link, self.name = controller, link, link.name
        self.sync_state = PRE_SYNC
        self.last_rx = now
        self.watchdog_tripped = False
        self.sip_due = 0.0
        self.requests = {"encoder": 0, "io": 0, "battery": 0}

    def on_frame(self, frame: bytes, now: float) -> bytes | None:
        """One complete ARCOS frame from the client -> the immediate reply, if any."""
        c = self.controller
        with c.lock:
            return c.handle(self, frame[3:-2], now)

    def on_close(self) -> None:
        """The link is gone: a session it held ends (the robot stops)."""
        self.controller.detach(self)


class ArcosController(ServerPackets):
    """The robot's ARCOS firmware over a model (see the module docstring).

    ``name``/``subtype``: what SYNC2 and CONFIG report. ``sip_ms``: SIP cycle (simulated ms);
    ``period``: wall seconds between ticks. ``watchdog_s``: wall seconds without a valid
    packet after which the session's robot is stopped (0 disables). ``laser``, ``georef``,
    ``reflectors``: the simulated laser, the world's georeference and its reflective wall
    segments (:mod:`robocli.sim.pioneer.simext`). ``state_of_charge``: report the battery's
    state of charge in the SIP; by default 0, as MobileSim/AMRISim send it (the vendor SDK
    then shows volts).
    """

    def __init__(
        self, model: PioneerModel, *, name: str, subtype: str, sip_ms: float,
        period: float, watchdog_s: float, laser: LaserSpec | None = None,
        georef: Georef | None = None, seed: int = 0,
        reflectors: Sequence[Sequence[float]] = (), state_of_charge: bool = False,
    ) -> None:  # fmt: skip
        self.model, self.params = model, model.params
        self.report_soc = state_of_charge
        self.name, self.subtype = name, subtype
        self.sip_ms, self.watchdog_s = sip_ms, watchdog_s
        self._dt, self._period = sip_ms / 1000.0, period
        self.lock = threading.RLock()
        self.links: list[ArcosSession] = []  #: every link's session
        self.holder: ArcosSession | None = None  #: the session that OPENed the robot
        self.last: ArcosSession | None = None  #: the session that last sent a packet
        self.commands: collections.Counter[str] = collections.Counter()
        self.sessions = self.watchdog_trips = self.sips = 0
        self.sonar_on = False
        self._sonar_cursor = 0
        self._digin, self.digout, self._anport = 0xFF, 0xFF, 0
        self.last_say: tuple[tuple[int, int], ...] = ()
        self.ext = SimExtensions(
            model, laser=laser, georef=georef, sip_ms=sip_ms, period=period, seed=seed,
            reflectors=reflectors,
        )  # fmt: skip
        self._handlers = {**self._make_handlers(), **self.ext.handlers()}
        self._config_cache: tuple[tuple[float, ...], bytes] | None = None
        #: commands decoded, by payload: a client repeats the same few (CONFIG requests,
        #: PULSE, set-points), and decoding is the larger part of a request's cost
        self._decoded: dict[bytes, DecodedCommand] = {}
        head = ("x", "y", "th", "lvel", "rvel", "battery", "stall_bumpers", "control", "flags")
        empty: dict[str, Any] = {**dict.fromkeys(head, 0), "compass": 0, "sonar": ()}
        self._sip_fixed = len(encode_sip_body({**empty, **self._sip_tail()}))
        self._sonar_k_max = max(0, (MAX_PAYLOAD - self._sip_fixed) // 3)

    # ---------------------------------------------------------------- links and ticks

    def attach(self, link: Link) -> ArcosSession:
        """The session of a new link (a :data:`~robocli.serving.server.SessionFactory`)."""
        with self.lock:
            session = ArcosSession(self, link, time.monotonic())
            self.links.append(session)
        return session

    def detach(self, session: ArcosSession) -> None:
        """Forget a link's session; a session it held ends."""
        with self.lock:
            self._end_session(session, "link closed")
            if session in self.links:
                self.links.remove(session)
            if self.last is session:
                self.last = None

    def tick(self, now: float) -> tuple[ArcosSession | None, bytes]:
        """One period: step the model, run the watchdog, and return the packets due (SIP and
        requested IO/encoder/battery) with the session to push them to."""
        with self.lock:
            self.model.step(self._dt)
            self._housekeeping(now)
            holder = self.holder
            data = self._session_packets(holder, now) if holder is not None else b""
        return holder, data

    def odom_raw(self) -> tuple[int, int, int]:
        """The SIP's (x, y, th) odometry counters now."""
        with self.lock:
            return self._odom_raw()

    def _housekeeping(self, now: float) -> None:
        link = self.holder
        if (
            link is not None
            and self.watchdog_s > 0
            and not link.watchdog_tripped
            and now - link.last_rx > self.watchdog_s
        ):
            link.watchdog_tripped = True
            self.watchdog_trips += 1
            self.model.halt()
            log.warning(
                "%s: no valid packet for %.0f ms (watchdog %.0f ms): stopping the robot",
                link.name, (now - link.last_rx) * 1e3, self.watchdog_s * 1e3,
            )  # fmt: skip
        for other in self.links:
            in_handshake = AFTER_SYNC0 <= other.sync_state <= AFTER_SYNC2
            if in_handshake and now - other.last_rx > HANDSHAKE_TIMEOUT_S:
                log.info("%s: handshake abandoned; back to pre-sync", other.name)
                other.sync_state = PRE_SYNC

    # ---------------------------------------------------------------- protocol (lock held)

    def handle(self, link: ArcosSession, payload: bytes, now: float) -> bytes | None:
        """One valid client packet (type + args) -> the immediate reply, if any."""
        link.last_rx = now
        link.watchdog_tripped = False
        self.last = link
        cmd = self._decoded.get(payload)
        if cmd is None:
            try:
                cmd = decode_command(payload)
            except (ConstructError, RobocliError, ValueError) as exc:
                log.debug("%s: undecodable command %s (%s)", link.name, payload.hex(" "), exc)
                return None
            if len(self._decoded) >= _DECODED_MAX:
                self._decoded.clear()
            self._decoded[payload] = cmd
        if link.sync_state == IN_SESSION:
            self.commands[_COMMAND_NAMES[cmd.command]] += 1  # (cmd.name: an enum look-up)
            if cmd.command == _SETO:  # its data is not an ordinary argument
                self.ext.seto(payload)
                return None
            handler = self._handlers.get(cmd.command)
            if handler is None:
                log.debug("%s: ignoring command %s", link.name, cmd.name)
                return None
            return handler(link, cmd.arg)
        return self._pre_session(link, cmd.command, cmd.arg)

    def _pre_session(self, link: ArcosSession, c: int, arg: object) -> bytes | None:
        state = link.sync_state
        if c == 0:
            self.commands["SYNC0"] += 1
            link.sync_state = AFTER_SYNC0
            return frame(b"\x00")
        if c == 1 and state == AFTER_SYNC0:
            self.commands["SYNC1"] += 1
            link.sync_state = AFTER_SYNC1
            return frame(b"\x01")
        if c == 2 and state == AFTER_SYNC1:
            self.commands["SYNC2"] += 1
            link.sync_state = AFTER_SYNC2
            link.link.establish()  # the handshake is done: the connection keeps its place
            return encode_server(
                PacketType.SYNC2, {"name": self.name, "type": "Pioneer", "subtype": self.subtype}
            )
        if c == 1 and state == AFTER_SYNC2:
            self.commands["OPEN"] += 1
            self._open(link)
            return None
        if c in (1, 2):
            self.commands[("OPEN", "CLOSE")[c - 1] if arg is not None else f"SYNC{c}"] += 1
            log.debug("%s: out-of-order sync %d in state %d; restarting", link.name, c, state)
            link.sync_state = PRE_SYNC
        else:
            self.commands[_COMMAND_NAMES[c]] += 1
            log.debug("%s: command %s before OPEN ignored", link.name, _COMMAND_NAMES[c])
        return None

    def _open(self, link: ArcosSession) -> None:
        holder = self.holder
        if holder is not None and holder is not link:
            log.warning("%s: OPEN refused, %s holds the session", link.name, holder.name)
            link.sync_state = PRE_SYNC
            return
        self.holder = link
        link.sync_state = IN_SESSION
        link.requests = dict.fromkeys(link.requests, 0)
        link.sip_due = time.monotonic() + self._period / 2.0  # first SIP ~ one period after OPEN
        self.sessions += 1
        self.model.reset_session()
        self.ext.open_session()
        self.sonar_on, self._sonar_cursor = True, 0
        log.info("%s: session %d open", link.name, self.sessions)

    def _end_session(self, link: ArcosSession, why: str) -> None:
        link.sync_state = PRE_SYNC
        if self.holder is not link:
            return
        self.holder = None
        self.model.reset_session()
        self.ext.open_session()
        self.sonar_on = False
        log.info("%s: session ended (%s)", link.name, why)

    def _session_packets(self, link: ArcosSession, now: float) -> bytes:
        if now < link.sip_due:
            return b""
        packets = [self.ext.before_sip(self.sips, now), self._sip()]
        self.sips += 1
        for kind, build in (
            ("encoder", self._encoder_packet),
            ("io", self._io_packet),
            ("battery", self._battery_packet),
        ):
            mode = link.requests[kind]
            if mode:
                packets.append(build())
                if mode == 1:
                    link.requests[kind] = 0
        packets.append(self.ext.after_sip(self.sips))
        return b"".join(packets)

    # ---------------------------------------------------------------- in-session commands

    def _make_handlers(self) -> dict[int, Callable[[ArcosSession, Any], bytes | None]]:
        return {
            Command.PULSE: lambda link, arg: None,
            Command.OPEN: lambda link, arg: None,
            Command.CLOSE: self._cmd_close,
            Command.ENABLE: self._cmd_enable,
            Command.SETA: self._cmd_seta,
            Command.SETV: self._cmd_setv,
            Command.MOVE: self._motion(lambda a: self.model.move(a / 1000.0)),
            Command.ROTATE: self._motion(lambda a: self.model.set_rot(math.radians(a))),
            Command.SETRV: self._cmd_setrv,
            Command.VEL: self._motion(lambda a: self.model.set_trans(a / 1000.0)),
            Command.HEAD: self._motion(lambda a: self.model.head(math.radians(a))),
            Command.DHEAD: self._motion(self._dhead),
            Command.SAY: self._cmd_say,
            Command.CONFIG: lambda link, arg: self._config_packet(),
            Command.ENCODER: self._request("encoder"),
            Command.RVEL: self._motion(lambda a: self.model.set_rot(math.radians(a))),
            Command.DCHEAD: self._motion(self._dchead),
            Command.SETRA: self._cmd_setra,
            Command.SONAR: self._cmd_sonar,
            Command.STOP: lambda link, arg: self.model.halt(),
            Command.DIGOUT: self._cmd_digout,
            Command.VEL2: self._motion(self._vel2),
            Command.ADSEL: self._cmd_adsel,
            Command.IOREQUEST: self._request("io"),
            Command.BUMPSTALL: self._cmd_bumpstall,
            Command.ESTOP: lambda link, arg: self.model.emergency_stop(),
            Command.BATTERYINFO: self._request("battery"),
            Command.BATTEST: self._cmd_battest,
        }

    def _motion(self, apply: Callable[[int], None]) -> Callable[[ArcosSession, Any], None]:
        """A motion command taking an int: ignored (logged) while the motors are disabled."""

        def handler(link: ArcosSession, arg: Any) -> None:
            if not isinstance(arg, int):
                log.debug("%s: motion command without an int argument ignored", link.name)
            elif not self.model.motors:
                log.debug("%s: motors disabled; motion command ignored", link.name)
            else:
                apply(arg)

        return handler

    def _request(self, kind: str) -> Callable[[ArcosSession, Any], None]:
        def handler(link: ArcosSession, arg: Any) -> None:
            link.requests[kind] = int(clamp(_int_arg(arg, 1), 0, 2))

        return handler

    def _cmd_close(self, link: ArcosSession, arg: Any) -> None:
        self._end_session(link, "CLOSE")

    def _cmd_enable(self, link: ArcosSession, arg: Any) -> None:
        self.model.set_motors(_int_arg(arg) != 0)

    def _cmd_seta(self, link: ArcosSession, arg: Any) -> None:
        a = _int_arg(arg) / 1000.0
        if a > 0:
            self.model.limits.trans_accel = a
        elif a < 0:
            self.model.limits.trans_decel = -a

    def _cmd_setra(self, link: ArcosSession, arg: Any) -> None:
        a = math.radians(_int_arg(arg))
        if a > 0:
            self.model.limits.rot_accel = a
        elif a < 0:
            self.model.limits.rot_decel = -a

    def _cmd_setv(self, link: ArcosSession, arg: Any) -> None:
        top = self.params.max_velocity  # as ARCOS: never above CONFIG's transvel_top
        self.model.limits.trans_vel_max = min(top, abs(_int_arg(arg)) / 1000.0)

    def _cmd_setrv(self, link: ArcosSession, arg: Any) -> None:
        top = self.params.max_rot_velocity
        self.model.limits.rot_vel_max = min(top, math.radians(abs(_int_arg(arg))))

    def _dhead(self, deg: int) -> None:
        self.model.head(self.model.odom[2] + math.radians(deg))

    def _dchead(self, deg: int) -> None:
        r = self.model
        base = r.head_set if r.rot_mode == "head" else r.odom[2]
        r.head(base + math.radians(deg))

    def _vel2(self, arg: int) -> None:
        left, right = split_two_bytes(arg)
        div = self.params.vel2_divisor / 1000.0
        self.model.wheels(left * div, right * div)

    def _cmd_say(self, link: ArcosSession, arg: Any) -> None:
        if isinstance(arg, bytes):
            pairs = zip(arg[0::2], arg[1::2], strict=False)
            self.last_say = tuple((d * 20, tone) for d, tone in pairs)

    def _cmd_sonar(self, link: ArcosSession, arg: Any) -> None:
        self.sonar_on = _int_arg(arg) != 0

    def _cmd_digout(self, link: ArcosSession, arg: Any) -> None:
        mask, values = (b & 0xFF for b in split_two_bytes(_int_arg(arg)))
        self.digout = (self.digout & ~mask | values & mask) & 0xFF

    def _cmd_adsel(self, link: ArcosSession, arg: Any) -> None:
        self._anport = _int_arg(arg) & 0xFF

    def _cmd_bumpstall(self, link: ArcosSession, arg: Any) -> None:
        self.model.bump_stall = _int_arg(arg) & 3

    def _cmd_battest(self, link: ArcosSession, arg: Any) -> None:
        dv = _int_arg(arg)
        self.model.battery_override = dv / 10.0 if dv > 0 else None


def _int_arg(arg: Any, default: int = 0) -> int:
    return arg if isinstance(arg, int) else default


def _command_name(c: int) -> str:
    try:
        return Command(c).name
    except ValueError:
        return f"CMD_{c}"


#: every command byte's name, computed once: a command is counted on every request's path
_COMMAND_NAMES = tuple(_command_name(c) for c in range(256))
_SETO = int(Command.SETO)
_DECODED_MAX = 256  #: distinct payloads the decoded-command cache holds before it restarts
