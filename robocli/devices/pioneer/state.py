"""Pioneer state in SI units: a pure function of the SIPs received (no threads, no I/O)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from robocli.errors import ProtocolError
from robocli.protocols import arcos, layout
from robocli.robots.geometry import wrap_pi
from robocli.robots.pioneer import RobotParams


@dataclass(frozen=True)
class RobotIdentity:
    """What the robot says of itself in the SYNC2 reply."""

    name: str
    type: str
    subtype: str


@dataclass(frozen=True)
class PioneerState:
    """One SIP in SI units. Pose is odometry (15-bit counters unwrapped)."""

    t: float  #: monotonic receive time (s)
    x: float  #: m
    y: float  #: m
    th: float  #: rad, in [-pi, pi)
    v: float  #: m/s, mean of the wheel speeds
    w: float  #: rad/s, counter-clockwise positive
    left_velocity: float  #: m/s
    right_velocity: float  #: m/s
    battery: float  #: V
    #: 0..1; None when the robot does not model it (it sends 0, as MobileSim and AMRISim do,
    #: and has sent nothing else on this link)
    state_of_charge: float | None
    charge_state: int | None
    motors_enabled: bool
    estop: bool
    sonar_enabled: bool
    stall_left: bool
    stall_right: bool
    bumpers_front: int  #: bit mask of the front bump ring (bit 0 = first switch)
    bumpers_rear: int
    sonar: tuple[float, ...]  #: m, per sonar index; nan until first reading
    sonar_time: tuple[float, ...]  #: monotonic time each range was last updated
    digin: int
    digout: int
    analog: float  #: V, the port chosen with select_analog
    temperature: float | None  #: deg C
    sip_count: int

    @property
    def pose(self) -> tuple[float, float, float]:
        return (self.x, self.y, self.th)

    @property
    def bumped(self) -> bool:
        return bool(self.bumpers_front or self.bumpers_rear)

    @property
    def stalled(self) -> bool:
        return self.stall_left or self.stall_right


class Odometry:
    """The odometry position (raw units) tracked from the deltas of the 15-bit x/y counters,
    as the vendor SDK does.

    - The first SIP's counters are read as signed 15-bit values, so a robot whose counters
      are slightly negative at OPEN starts slightly negative, not 16 m away.
    - Each later SIP adds the wrapped delta (a jump of more than 0x1000 units is a wrap).
    - After :meth:`expect_reset` (a SETO was sent) the position is zero at once, and the
      robot's own counters are re-read as absolute on the first of the next SIPs that shows
      them reset: a robot applies SETO on its next cycle or later (the vendor simulator shows
      it in the second SIP after the command), and until then its old counters still arrive.
      With receive times, the window also stays open :data:`RESET_WINDOW_S` after the SETO:
      a lagging client may read more than 4 SIPs that the robot sent before the SETO.
    """

    RESET_WINDOW = 4  #: SIPs in which the robot's reset is looked for
    RESET_WINDOW_S = 1.0  #: and at least this long (s) after the SETO, given receive times

    def __init__(self) -> None:
        self.raw: tuple[int, int] | None = None
        self.x = 0
        self.y = 0
        self._reset_left = 0
        self._reset_until = -math.inf

    def expect_reset(self, now: float | None = None) -> None:
        """A SETO went out (at ``now``): the position is (0, 0) from now on."""
        self.x = self.y = 0
        self._reset_left = self.RESET_WINDOW
        self._reset_until = -math.inf if now is None else now + self.RESET_WINDOW_S

    def update(self, rx: int, ry: int, now: float | None = None) -> tuple[int, int]:
        """The position after a SIP with counters ``rx``, ``ry`` (received at ``now``)."""
        rx &= 0x7FFF
        ry &= 0x7FFF
        waiting = self._reset_left > 0 or (now is not None and now < self._reset_until)
        if self.raw is None:
            self.x, self.y = _signed15(rx), _signed15(ry)
        elif waiting and self._looks_reset(rx, ry):
            self.x, self.y = _signed15(rx), _signed15(ry)
            self._reset_left, self._reset_until = 0, -math.inf
        else:
            self.x += _delta15(rx - self.raw[0])
            self.y += _delta15(ry - self.raw[1])
            self._reset_left = max(0, self._reset_left - 1)
        self.raw = (rx, ry)
        return self.x, self.y

    def _looks_reset(self, rx: int, ry: int) -> bool:
        """The counters moved to zero: at most half as far from it as before, and moved."""
        assert self.raw is not None
        old = max(abs(_signed15(self.raw[0])), abs(_signed15(self.raw[1])))
        new = max(abs(_signed15(rx)), abs(_signed15(ry)))
        return (rx, ry) != self.raw and new <= old // 2


def _signed15(v: int) -> int:
    return v - 0x8000 if v >= 0x4000 else v


def _delta15(d: int) -> int:
    if d > 0x1000:
        d -= 0x8000
    elif d < -0x1000:
        d += 0x8000
    return d


# What the reader needs from every SIP, as struct views of the SIP declaration: the odometry
# counters (the first two fields) and the sonar readings that follow the fixed head. The rest
# is decoded only when the program asks for the state.
_SIP_FIELDS = list(arcos.SIP.subcons)
_SONAR_AT = [sub.name for sub in _SIP_FIELDS].index("sonar")
_XY = layout.struct_of(type(arcos.SIP)(*_SIP_FIELDS[:2]), "SIP.x/y")
_HEAD_SIZE = layout.struct_of(type(arcos.SIP)(*_SIP_FIELDS[:_SONAR_AT]), "SIP head").size
_SONAR = layout.struct_of(arcos.SonarReading, "SIP.sonar")
_FLAGS_INDEX = [sub.name for sub in _SIP_FIELDS].index("flags")
_FLAGS_AT = layout.struct_of(type(arcos.SIP)(*_SIP_FIELDS[:_FLAGS_INDEX]), "SIP head").size
_FLAGS = layout.struct_of(type(arcos.SIP)(_SIP_FIELDS[_FLAGS_INDEX]), "SIP.flags")
_SOC_INDEX = [sub.name for sub in _SIP_FIELDS].index("state_of_charge")
# the state of charge's offset after the sonar readings (the groups before it, all present)
_SOC_AFTER_SONAR = layout.struct_of(
    type(arcos.SIP)(*_SIP_FIELDS[_SONAR_AT + 1 : _SOC_INDEX]), "SIP tail"
).size


def sip_state_of_charge(body: bytes) -> int | None:
    """The state of charge byte (percent) of a SIP body checked by :func:`sip_essentials`,
    or None for a SIP too short to carry it."""
    at = _HEAD_SIZE + 1 + body[_HEAD_SIZE] * _SONAR.size + _SOC_AFTER_SONAR
    return body[at] if at < len(body) else None


def sip_motors_on(body: bytes) -> bool:
    """The motors-enabled flag of a SIP body checked by :func:`sip_essentials`."""
    return bool(_FLAGS.unpack_from(body, _FLAGS_AT)[0] & arcos.FLAG_MOTORS_ON)


def sip_essentials(body: bytes) -> tuple[int, int, list[tuple[int, int]]]:
    """Raw odometry x, y and the ``(number, range)`` sonar readings of a SIP body (after the
    type byte), checking only that the body holds them: the per-SIP work of a client."""
    end = _HEAD_SIZE + 1
    if len(body) >= end:
        end += body[_HEAD_SIZE] * _SONAR.size
    if len(body) < end:
        raise ProtocolError(f"ARCOS SIP of {len(body)} bytes is shorter than its fields")
    x, y = _XY.unpack_from(body, 0)
    return x, y, list(_SONAR.iter_unpack(body[_HEAD_SIZE + 1 : end]))


def build_state(
    sip: dict[str, Any],
    t: float,
    odo: tuple[int, int],
    sonar: tuple[float, ...],
    sonar_time: tuple[float, ...],
    params: RobotParams,
    sip_count: int,
    *,
    soc_seen: bool = True,
) -> PioneerState:
    """A decoded SIP (:func:`robocli.protocols.arcos.decode_sip`) in SI units.

    ``odo`` is the unwrapped odometry in position units, ``sonar`` the latest range per
    sonar index in metres, ``t`` the monotonic receive time. ``soc_seen``: a SIP of this
    link reported a non-zero state of charge; until then a 0 means "not modelled" (as
    MobileSim/AMRISim send it, and the vendor SDK reads it) and comes out as None.
    """
    p = params
    lv = sip["lvel"] * p.vel_conv / 1000.0
    rv = sip["rvel"] * p.vel_conv / 1000.0
    rotvel = sip["rotvel"]
    w = math.radians(rotvel / 10.0) if rotvel is not None else (rv - lv) / 2 * p.diff_conv * 1e3
    batx10 = sip["battery_x10"]
    io = sip["io"] or {}
    soc = sip["state_of_charge"]
    temp = sip["temperature"]
    flags = sip["flags"]
    sb = sip["stall_bumpers"]
    return PioneerState(
        t=t,
        x=odo[0] * p.dist_conv / 1000.0,
        y=odo[1] * p.dist_conv / 1000.0,
        th=wrap_pi(sip["th"] * p.angle_conv),
        v=(lv + rv) / 2,
        w=w,
        left_velocity=lv,
        right_velocity=rv,
        battery=(batx10 if batx10 else sip["battery"]) / 10.0,
        state_of_charge=soc / 100.0 if soc is not None and (soc or soc_seen) else None,
        charge_state=sip["charge_state"],
        motors_enabled=bool(flags & arcos.FLAG_MOTORS_ON),
        estop=bool(flags & arcos.FLAG_ESTOP),
        sonar_enabled=bool(flags & arcos.FLAG_SONAR_MASK),
        stall_left=bool(sb & arcos.STALL_LEFT),
        stall_right=bool(sb & arcos.STALL_RIGHT),
        bumpers_front=(sb & arcos.BUMPERS_FRONT_MASK) >> 9,
        bumpers_rear=(sb & arcos.BUMPERS_REAR_MASK) >> 1,
        sonar=sonar,
        sonar_time=sonar_time,
        digin=io.get("digin", 0),
        digout=io.get("digout", 0),
        analog=io.get("analog", 0) * 5.0 / 255.0,
        temperature=None if temp is None or temp == -127 else float(temp),
        sip_count=sip_count,
    )


__all__ = [
    "Odometry",
    "PioneerState",
    "RobotIdentity",
    "build_state",
    "sip_essentials",
    "sip_motors_on",
]
