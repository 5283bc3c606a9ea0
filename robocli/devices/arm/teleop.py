"""Jogging an arm from the keyboard, without a terminal: keys in, short motions out.

One joint at a time (``1``..``6`` pick it, arrows or WASD move it) or the TCP along x, y, z
(``c``; arrows/WASD move in x and y, ``r``/``f`` in z, through inverse kinematics). Terminals
report key presses and auto-repeats, never releases, so a key counts as held while presses
keep coming and ``release_timeout`` after the last one the arm is sent STOP (-4).

* **ABB** (download servers): every ``period`` a one-point trajectory reaching ``horizon``
  seconds ahead is downloaded (-1, -3); each activation pre-empts the running one, so the
  arm moves on while the key is held and stops short of the target when it is not renewed.
* **Streaming servers** (``stream=True``): one point per ``period``, each ``period`` further
  on, sequence 0 first; the lead over the measured joints is bounded.

Speeds are fractions of the model's joint speed limits (joint mode) or m/s (Cartesian);
a target beyond a joint limit is clipped to it, and a jog that cannot move at all is refused
with a message (nothing is sent). STOP is sent on release, on :meth:`ArmTeleop.close`
(quit, Ctrl-C, any error) and when the state stream goes silent. Times are explicit
arguments, so tests drive the controller on their own clock.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from robocli.closing import Closing
from robocli.devices.keys import QUIT_KEYS, fresh_keys
from robocli.errors import RobocliError, TimeoutError
from robocli.kinematics import LimitError, UnreachableError, fk, ik

if TYPE_CHECKING:
    from robocli.devices.arm import Arm
    from robocli.kinematics.model import RobotModel

__all__ = ["ArmTeleop", "Jog", "JogKeys", "jog_target", "run_arm_teleop"]

log = logging.getLogger("robocli.devices.arm.teleop")

FloatArray = npt.NDArray[np.float64]

#: key -> direction: (+1 / -1) in joint mode, (axis, sign) in Cartesian mode
JOINT_KEYS = {"up": 1, "w": 1, "right": 1, "d": 1, "down": -1, "s": -1, "left": -1, "a": -1}
CARTESIAN_KEYS = {
    "up": (0, 1), "w": (0, 1), "down": (0, -1), "s": (0, -1),
    "left": (1, 1), "a": (1, 1), "right": (1, -1), "d": (1, -1),
    "r": (2, 1), "f": (2, -1),
}  # fmt: skip
STOP_KEYS = frozenset({"space", " "})
SPEED_STEP = 1.5  #: ``+`` / ``-`` multiply / divide the speeds by this
AXES = "xyz"


@dataclass(frozen=True)
class Jog:
    """One held direction: ``kind`` ``"joint"`` (``axis`` = joint index) or ``"cartesian"``
    (``axis`` 0, 1, 2 = x, y, z), ``sign`` +1 or -1."""

    kind: str
    axis: int
    sign: int

    def __str__(self) -> str:
        name = f"J{self.axis + 1}" if self.kind == "joint" else AXES[self.axis]
        return f"{name}{'+' if self.sign > 0 else '-'}"


class JogKeys:
    """Key presses -> the held :class:`Jog` (pure logic, explicit times)."""

    def __init__(self, n_joints: int, release_timeout: float = 0.45) -> None:
        self.n_joints, self.release_timeout = n_joints, release_timeout
        self.mode = "joint"
        self.joint = 0  #: the selected joint (0-based)
        self.scale = 1.0  #: speed multiplier (``+``/``-``)
        self.quit = False
        self._jog: Jog | None = None
        self._last = -math.inf

    def key(self, name: str, now: float) -> None:
        """Feed one key press (``up``, ``w``, ``1``, ``c``, ``space``, ``q``...)."""
        name = name if len(name) > 1 else name.lower()
        if name in QUIT_KEYS:
            self.quit, self._jog = True, None
        elif name in STOP_KEYS:
            self._jog = None
        elif name in ("j", "c"):
            self.mode, self._jog = ("joint" if name == "j" else "cartesian"), None
        elif name.isdigit() and 1 <= int(name) <= self.n_joints:
            self.mode, self.joint, self._jog = "joint", int(name) - 1, None
        elif name in ("+", "="):
            self.scale = min(self.scale * SPEED_STEP, 10.0)
        elif name == "-":
            self.scale = max(self.scale / SPEED_STEP, 0.05)
        elif self.mode == "joint" and name in JOINT_KEYS:
            self._jog, self._last = Jog("joint", self.joint, JOINT_KEYS[name]), now
        elif self.mode == "cartesian" and name in CARTESIAN_KEYS:
            axis, sign = CARTESIAN_KEYS[name]
            self._jog, self._last = Jog("cartesian", axis, sign), now

    def jog(self, now: float) -> Jog | None:
        """The held jog at ``now``: None once no press came for ``release_timeout``."""
        if self.quit or now - self._last > self.release_timeout:
            self._jog = None
        return self._jog


def jog_target(model: RobotModel, q: npt.ArrayLike, jog: Jog, dt: float, joint_speed: float,
               cart_speed: float) -> tuple[FloatArray, float]:  # fmt: skip
    """Where ``jog`` takes the arm from ``q`` (rad) in ``dt`` s, and the time that needs.

    Joint mode moves at ``joint_speed`` (a fraction of the joint's speed limit), clipped to
    the joint's range; Cartesian mode moves the flange ``cart_speed`` m/s along an axis,
    through IK on the branch closest to ``q``, slowed down so that no joint exceeds
    ``joint_speed`` of its limit. Raises :class:`LimitError` when the joint is at its limit
    in that direction, :class:`UnreachableError` when the Cartesian target is out of reach.
    """
    q = np.asarray(q, dtype=float)
    lo, hi = model.limits[:, 0], model.limits[:, 1]
    fraction = min(max(joint_speed, 1e-3), 1.0)
    if jog.kind == "joint":
        j = jog.axis
        step = jog.sign * fraction * model.max_speed[j] * dt
        target = q.copy()
        target[j] = min(max(q[j] + step, lo[j]), hi[j])
        if abs(target[j] - q[j]) < 1e-4:
            edge = "upper" if jog.sign > 0 else "lower"
            value = math.degrees(hi[j] if jog.sign > 0 else lo[j])
            raise LimitError(f"joint {j + 1} is at its {edge} limit ({value:+.1f} deg)")
        return target, max(dt * abs(target[j] - q[j]) / abs(step), 0.05)
    pose = fk(model, q)[0]
    pose[jog.axis, 3] += jog.sign * cart_speed * dt
    target = ik(model, pose, q)
    if not bool(np.all(model.within_limits(target))):
        k = int(np.argmax(~model.within_limits(target)))
        raise LimitError(f"{jog}: joint {k + 1} would leave its range")
    need = float(np.max(np.abs(target - q) / (fraction * model.max_speed)))
    return target, max(dt, need)


class ArmTeleop(Closing):
    """Jog a connected :class:`~robocli.devices.arm.Arm` (state and motion ports).

    Feed keys with :meth:`key`, call :meth:`step` often (every few tens of ms); close it
    (or use it as a context manager) to send the final STOP. ``joint_speed``: fraction of the
    joint speed limits; ``cart_speed``: m/s; both scaled by ``+``/``-``. ``stale`` s without
    a joint sample while jogging stops the arm and raises :class:`TimeoutError`.
    """

    def __init__(self, arm: Arm, *, stream: bool = False, joint_speed: float = 0.1,
                 cart_speed: float = 0.05, period: float = 0.1, horizon: float = 0.3,
                 release_timeout: float = 0.45, stale: float = 1.0,
                 clock: Callable[[], float] = time.monotonic) -> None:  # fmt: skip
        self.arm, self.stream, self.period, self.horizon = arm, stream, period, horizon
        self.joint_speed, self.cart_speed, self.stale = joint_speed, cart_speed, stale
        self.keys = JogKeys(arm.robot.n_joints, release_timeout)
        self.clock = clock
        self.message = ""  #: why the last jog was refused (empty when it was not)
        self.jog: Jog | None = None  #: what is being sent now
        self.sent = {"trajectories": 0, "points": 0, "stops": 0}
        self._last_send = -math.inf
        self._moving = False  # motion commanded since the last STOP
        self._seq = 0  # streaming: the next sequence number
        self._lead: FloatArray | None = None  # streaming: the last point sent

    @property
    def quit(self) -> bool:
        return self.keys.quit

    def key(self, name: str, now: float | None = None) -> None:
        """One key press (see :class:`JogKeys`); a new direction is sent at the next step."""
        self.keys.key(name, self.clock() if now is None else now)

    def step(self, now: float | None = None) -> None:
        """Send what the held key asks for: STOP on release, a new motion every ``period``
        (at once when the direction changed). Raises the link's error once a link is lost,
        even while idle (:meth:`Arm.check`)."""
        self.arm.check()
        now = self.clock() if now is None else now
        jog = self.keys.jog(now)
        if jog is None:
            self.jog = None
            if self._moving:
                self.stop()
            return
        sample = self.arm.joints
        if sample is None or now - sample.t > self.stale:
            self.stop()
            raise TimeoutError(f"no joint state for {self.stale:g} s while jogging: stopped")
        if jog == self.jog and now - self._last_send < self.period:
            return
        if jog != self.jog and self._moving and self.stream:
            self.stop()  # a new direction starts a new stream at sequence 0
        self.jog, self._last_send = jog, now
        try:
            self._send(jog, np.asarray(sample.joints, dtype=float))
            self.message = ""
        except (LimitError, UnreachableError) as exc:
            self.message = str(exc)
            if self._moving:
                self.stop()

    def _send(self, jog: Jog, q: FloatArray) -> None:
        scale = self.keys.scale
        speeds = (self.joint_speed * scale, self.cart_speed * scale)
        if not self.stream:  # ABB: a short trajectory that pre-empts the running one
            target, duration = jog_target(self.arm.robot, q, jog, self.horizon, *speeds)
            self._moving = True
            self.arm.download(([0.0], [target]), first_duration=duration)
            self.sent["trajectories"] += 1
            self.sent["points"] += 2
            return
        base = q if self._lead is None else self._lead
        if self._lead is not None and self._ahead(q) > 3:
            return  # the server is behind: let it catch up
        target, duration = jog_target(self.arm.robot, base, jog, self.period, *speeds)
        self._moving = True
        velocity = min(1.0, self.joint_speed * scale)
        self.arm.send_point(self._seq, target, velocity=velocity, duration=duration)
        self._seq += 1
        self._lead = target
        self.sent["points"] += 1

    def _ahead(self, q: FloatArray) -> float:
        """How many periods' worth of motion the last streamed point leads ``q`` by."""
        assert self._lead is not None
        per_period = self.joint_speed * self.keys.scale * self.arm.robot.max_speed * self.period
        return float(np.max(np.abs(self._lead - q) / per_period))

    def stop(self) -> None:
        """STOP (-4) now (acknowledged); the next jog starts afresh."""
        self._moving, self._seq, self._lead, self.jog = False, 0, None, None
        self.arm.stop()
        self.sent["stops"] += 1

    def close(self) -> None:
        """The final STOP, best effort (the link may be gone: the session's own emergency
        stop then was sent when it failed)."""
        try:
            self.stop()
        except RobocliError as exc:
            log.warning("teleop: final STOP not acknowledged: %s", exc)

    def status(self) -> str:
        """One line of at most 80 columns: selection, jog, speed scale, joints (deg), TCP
        (m); the last refusal instead of the joints when there is one."""
        k = self.keys
        what = f"J{k.joint + 1}" if k.mode == "joint" else "TCP"
        head = f"{what:<3} {str(self.jog) if self.jog else 'idle':<4} x{k.scale:<4.2g}"
        sample = self.arm.joints
        if self.message or sample is None:
            return f"{head} {self.message or 'no state yet'}"[:80]
        joints = " ".join(f"{v:+.1f}" for v in sample.degrees())
        x, y, z = fk(self.arm.robot, list(sample.joints))[0][:3, 3]
        return f"{head} deg {joints}  tcp {x:.3f} {y:.3f} {z:.3f} m"[:80]


def run_arm_teleop(teleop: ArmTeleop, read_key: Callable[[float], str | None],
                   on_update: Callable[[ArmTeleop], None] | None = None,
                   period: float = 0.05) -> None:  # fmt: skip
    """Jog until a quit key; ``read_key(timeout)`` gives a key name or None. STOP is sent on
    every way out (quit, an error, Ctrl-C, a lost link), and after a stall of this loop (keys
    typed meanwhile are discarded: :func:`~robocli.devices.keys.fresh_keys`)."""
    read_key = fresh_keys(read_key, teleop.keys.release_timeout, teleop.clock)
    try:
        while not teleop.quit:
            key = read_key(period)
            if key is not None:
                teleop.key(key)
            teleop.step()
            if on_update is not None:
                on_update(teleop)
    finally:
        teleop.close()
