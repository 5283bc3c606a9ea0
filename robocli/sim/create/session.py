"""The Create 2's Open Interface firmware in the simulator: modes, commands, sensors, stream.

:class:`CreateController` is the robot's one OI (shared by its links, guarded by
:attr:`CreateController.lock`); :class:`CreateSession` is one link's view of it (the serving
layer's :class:`~robocli.serving.links.ServerSession`). No sockets.

Rules, from the Create 2 OI Specification:

* modes off (0), passive (1), safe (2), full (3). Off takes only start (128), reset (7) and
  baud (129); start enters passive from any mode; safe (131, or 130) and full (132) need a
  started OI; stop (173) and reset go off and end the stream; power (133), spot, clean, max
  and seek dock (134..136, 143) go passive (their cleaning is not modelled);
* drive (137), drive direct (145), drive PWM (146), the motors (138, 144), LEDs (139), play
  (141), the digit and scheduling LEDs and buttons (162..165) only in safe or full mode;
  sensors (142), query list (149), stream (148), pause/resume (150), song (140), baud and
  the schedule (167, 168) in every mode but off; a command not allowed in the mode is
  ignored (counted in ``ignored``);
* safe mode: a wheel drop, a cliff while driving forward, or (``bump_stops``, on by default)
  a new bump stops the wheels and falls back to passive. The specification lists wheel drops,
  cliffs and the charger only; a bump is this simulator's addition, asked for by issue 25
  (``bump_stops=False`` gives the specification's rule);
* distance (19) and angle (20) are reset by every read of them; the stream sends its packets
  every 15 ms of robot time (header 19, byte count, id + data per packet, checksum).
"""

from __future__ import annotations

import collections
import threading
from dataclasses import dataclass, field
from typing import Any

from robocli.protocols import create_oi as oi
from robocli.protocols.create_oi import Op
from robocli.serving.links import Link
from robocli.sim.create.model import DROP_LEFT, DROP_RIGHT, CreateBody, wheel_setpoints
from robocli.sim.pioneer.model import clamp

__all__ = ["OFF", "PASSIVE", "SAFE", "FULL", "CreateController", "CreateSession"]

OFF, PASSIVE, SAFE, FULL = range(4)
RESET_BANNER = b"bl-start\r\nrobocli Create 2 simulator\r\n"
_EVERY_MODE = frozenset({Op.SENSORS, Op.QUERY_LIST, Op.STREAM, Op.PAUSE_RESUME_STREAM,
                         Op.SONG, Op.BAUD, Op.SCHEDULE, Op.SET_DAY_TIME, Op.START,
                         Op.RESET, Op.STOP, Op.SAFE, Op.CONTROL, Op.FULL, Op.POWER, Op.SPOT,
                         Op.CLEAN, Op.MAX, Op.SEEK_DOCK})  # fmt: skip
_PASSIVE_OPS = (Op.POWER, Op.SPOT, Op.CLEAN, Op.MAX, Op.SEEK_DOCK)


@dataclass
class Actuators:
    """What the OI was told to show or play (accepted, not acted out)."""

    leds: tuple[int, int, int] = (0, 0, 0)  #: bits, power colour, power intensity
    digits: bytes = b"    "
    motors: int = 0  #: 138's bits (brushes, vacuum)
    songs: dict[int, tuple[tuple[int, int], ...]] = field(default_factory=dict)
    played: list[int] = field(default_factory=list)  #: song numbers, in order
    baud: int = 115200


class CreateController:
    """The robot's OI state, one client at a time. Every method expects :attr:`lock` held
    unless it says otherwise."""

    def __init__(self, body: CreateBody, *, bump_stops: bool = True) -> None:
        self.lock = threading.RLock()
        self.body = body
        self.bump_stops = bump_stops
        self.mode = OFF
        self.holder: CreateSession | None = None
        self.stream: tuple[int, ...] | None = None  #: packet ids streamed, None: no stream
        self.stream_paused = False
        self.stream_frames = 0
        self.requested = (0, 0)  #: the last drive (137)'s velocity and radius (mm/s, mm)
        self.actuators = Actuators()
        self.commands: collections.Counter[str] = collections.Counter()
        self.ignored = 0  #: commands not allowed in the mode they came in
        self.bad_requests = 0  #: sensor, query or stream requests of packets that do not exist
        self.safety_trips = 0
        self._bumps_before = 0

    # ---------------------------------------------------------------- links

    def attach(self, link: Link) -> CreateSession:
        """The session of a new link (the serving layer's factory)."""
        return CreateSession(self, link)

    # ---------------------------------------------------------------- commands

    def command(self, session: CreateSession, data: bytes) -> bytes | None:
        """Handle one whole command; the reply, if any."""
        op, p = oi.parse_command(data)
        self.holder = session
        self.commands[op.name] += 1
        if self.mode == OFF and op not in (Op.START, Op.RESET, Op.BAUD):
            self.ignored += 1
            return None
        if op not in _EVERY_MODE and self.mode not in (SAFE, FULL):
            self.ignored += 1
            return None
        handler = getattr(self, f"_on_{op.name.lower()}", None)  # None: nothing to act out
        return handler(p) if handler is not None else None

    def _set_mode(self, mode: int) -> None:
        drives = mode in (SAFE, FULL)
        if not drives or self.mode not in (SAFE, FULL):  # the wheels stop, or start stopped
            self.body.enable(drives)
            self.requested = (0, 0)
        self.mode = mode
        if mode == OFF:
            self.stream, self.stream_paused = None, False
        if mode == SAFE:
            self._bumps_before = self.body.bumps()  # a bump already pressed is not new

    def _on_start(self, _: Any) -> None:
        self._set_mode(PASSIVE)

    def _on_safe(self, _: Any) -> None:
        self._set_mode(SAFE)

    _on_control = _on_safe

    def _on_full(self, _: Any) -> None:
        self._set_mode(FULL)

    def _on_stop(self, _: Any) -> None:
        self._set_mode(OFF)

    def _on_reset(self, _: Any) -> bytes:
        self._set_mode(OFF)
        self.actuators.songs.clear()
        return RESET_BANNER

    def _on_baud(self, p: dict[str, int]) -> None:
        if p["code"] < len(oi.BAUD_RATES):
            self.actuators.baud = oi.BAUD_RATES[p["code"]]

    def _on_drive(self, p: dict[str, int]) -> None:
        self.requested = (p["velocity"], p["radius"])
        self.body.wheels(*wheel_setpoints(p["velocity"], p["radius"]))

    def _on_drive_direct(self, p: dict[str, int]) -> None:
        self.requested = (0, 0)
        self.body.wheels(clamp(p["left"], -500, 500) / 1000.0,
                         clamp(p["right"], -500, 500) / 1000.0)  # fmt: skip

    def _on_drive_pwm(self, p: dict[str, int]) -> None:
        """PWM is not a speed: full duty cycle is taken as the wheel's top speed."""
        self.requested = (0, 0)
        top = self.body.model.params.max_velocity
        self.body.wheels(clamp(p["left"], -255, 255) / 255.0 * top,
                         clamp(p["right"], -255, 255) / 255.0 * top)  # fmt: skip

    def _on_motors(self, p: dict[str, int]) -> None:
        self.actuators.motors = p["bits"]

    def _on_leds(self, p: dict[str, int]) -> None:
        self.actuators.leds = (p["bits"], p["color"], p["intensity"])

    def _on_digit_leds_ascii(self, p: dict[str, Any]) -> None:
        self.actuators.digits = bytes(p["digits"])

    def _on_song(self, p: dict[str, Any]) -> None:
        notes = tuple((n["note"], n["duration"]) for n in p["notes"])
        self.actuators.songs[p["number"]] = notes

    def _on_play(self, p: dict[str, int]) -> None:
        if p["number"] in self.actuators.songs:
            self.actuators.played.append(p["number"])

    def _on_sensors(self, p: dict[str, int]) -> bytes | None:
        return self._packets((p["packet"],))

    def _on_query_list(self, p: dict[str, Any]) -> bytes | None:
        return self._packets(tuple(p["packets"]))

    def _on_stream(self, p: dict[str, Any]) -> None:
        ids = tuple(p["packets"])
        known = all(i in oi.PACKETS or i in oi.GROUPS for i in ids)
        if not known or sum(1 + oi.packet_size(i) for i in ids) > 255:  # n-bytes is one byte
            self.bad_requests += 1
            return
        self.stream, self.stream_paused = ids, False

    def _on_pause_resume_stream(self, p: dict[str, int]) -> None:
        self.stream_paused = p["resume"] == 0

    def _packets(self, ids: tuple[int, ...]) -> bytes | None:
        if not all(i in oi.PACKETS or i in oi.GROUPS for i in ids):
            self.bad_requests += 1  # the robot ignores the request
            return None
        return oi.encode_packets(ids, self.values(ids))

    # ---------------------------------------------------------------- sensors

    def values(self, ids: tuple[int, ...]) -> dict[str, int]:
        """Every sensor field's value now (distance and angle only when ``ids`` reads them:
        a read resets them)."""
        body, act = self.body, self.actuators
        wanted = {p for i in ids for p in oi.packet_ids(i)}
        millivolts, milliamps, charge, capacity = body.battery()
        left_ticks, right_ticks = body.encoders()
        left, right = body.model.wheel_speeds()
        cliffs = body.cliffs
        v: dict[str, int] = {
            "bumps_wheel_drops": body.bumps() | body.drops,
            "cliff_left": cliffs[0], "cliff_front_left": cliffs[1],
            "cliff_front_right": cliffs[2], "cliff_right": cliffs[3],
            "charging_state": 0, "voltage": millivolts, "current": milliamps,
            "temperature": 25, "battery_charge": charge, "battery_capacity": capacity,
            "oi_mode": self.mode, "song_number": act.played[-1] if act.played else 0,
            "stream_packets": len(self.stream or ()),
            "requested_velocity": self.requested[0], "requested_radius": self.requested[1],
            "requested_right_velocity": round(body.set_right * 1000),
            "requested_left_velocity": round(body.set_left * 1000),
            "left_encoder_counts": left_ticks, "right_encoder_counts": right_ticks,
            "left_motor_current": round(abs(left) * 400),
            "right_motor_current": round(abs(right) * 400),
        }  # fmt: skip
        if 19 in wanted:
            v["distance"] = body.take_distance()
        if 20 in wanted:
            v["angle"] = body.take_angle()
        return v

    # ---------------------------------------------------------------- the clock

    def tick(self, dt: float) -> tuple[CreateSession | None, bytes]:
        """Advance ``dt`` robot seconds; (the holder, a stream frame to send it, or b"")."""
        self.body.step(dt)
        self._safety()
        if self.stream is None or self.stream_paused or self.holder is None:
            return self.holder, b""
        self.stream_frames += 1
        return self.holder, oi.build_stream(self.stream, self.values(self.stream))

    def _safety(self) -> None:
        bumps = self.body.bumps()
        new_bump = bool(bumps & ~self._bumps_before)
        self._bumps_before = bumps
        if self.mode != SAFE:
            return
        forward = self.body.set_left + self.body.set_right > 0
        if (
            self.body.drops & (DROP_LEFT | DROP_RIGHT)
            or (any(self.body.cliffs) and forward)
            or (new_bump and self.bump_stops)
        ):
            self.safety_trips += 1
            self._set_mode(PASSIVE)

    def detach(self, session: CreateSession) -> None:
        """A link ended: its stream stops, and so do the wheels (a deliberate difference:
        the robot does not drive on with nobody at the other end)."""
        if self.holder is session:
            self.holder = None
            self.stream, self.stream_paused = None, False
            if self.mode in (SAFE, FULL):
                self.body.wheels(0.0, 0.0)


class CreateSession:
    """One link's session: hands its commands to the controller."""

    def __init__(self, ctl: CreateController, link: Link) -> None:
        self.ctl, self.link = ctl, link

    def on_frame(self, frame: bytes, now: float) -> bytes | None:
        with self.ctl.lock:
            return self.ctl.command(self, frame)

    def on_close(self) -> None:
        with self.ctl.lock:
            self.ctl.detach(self)
