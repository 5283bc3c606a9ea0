"""The controller side of the simulated ABB arm, without sockets.

:class:`Executor` moves the joints along activated trajectories on the simulator's clock.
:class:`ArmController` is what the RAPID tasks do (``ROS_motionServer``, ``ROS_motion``,
``ROS_stateServer``; docs/protocols/simple-message.md section 4) or, with
``profile="generic"``, what an industrial_robot_client streaming server does.
:class:`MotionSession` and :class:`StateSession` are one link's protocol state (a
:class:`~robocli.serving.server.ServerSession`): the serving layer hands them complete frames and
writes their replies. Every method that touches shared state takes the controller's lock.

Execution model: the points of an activated trajectory are knots of a cubic Hermite curve
whose knot velocities are finite differences of the points (as in the JSON logs), so the arm
passes exactly through every point at the time its durations give; a segment whose mean
speed would exceed a joint's speed limit is stretched to respect it.
"""

from __future__ import annotations

import bisect
import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robocli.errors import ProtocolError
from robocli.kinematics.model import RobotModel
from robocli.protocols import simple_message as sm
from robocli.protocols.simple_message import CommType, ReplyCode, SimpleMessageType, SpecialSeq
from robocli.serving.server import Link

__all__ = [
    "ABB_BUFFER",
    "PROFILES",
    "ArmController",
    "ControllerModel",
    "Executor",
    "MotionSession",
    "StateSession",
]

log = logging.getLogger("robocli.sim.abb.server")

FloatArray = npt.NDArray[np.float64]

PROFILES = ("abb", "generic")
ABB_BUFFER = 100  #: ``MAX_TRAJ_LENGTH`` of ``ROS_common.sys``
SKIP_TOLERANCE = math.radians(0.1)  #: first point skipped when this close (``ROS_motion.mod``)
MIN_SEGMENT_S = 1e-3  #: a zero or negative duration becomes the fastest allowed move
MAX_QUEUE = 1000  #: points a streaming server holds ahead of the arm (more: FAILURE)


@dataclass(frozen=True)
class ControllerModel:
    """How a real controller differs from ideal execution (all zero: exact).

    Each motion reply waits ``latency_ms`` plus a gamma-distributed extra (shape 4) whose
    standard deviation is ``jitter_ms`` (mean twice that): a skewed round trip with a floor,
    like the paper's Table 5. ``noise_rad`` adds Gaussian noise to reported joints;
    ``period_jitter_ms`` makes the state period a random one of that standard deviation, drawn
    afresh for each message (see :meth:`state_period_ms`); ``lag_ms`` delays execution after
    an activation.
    """

    latency_ms: float = 0.0
    jitter_ms: float = 0.0
    noise_rad: float = 0.0
    period_jitter_ms: float = 0.0
    lag_ms: float = 0.0

    @property
    def exact(self) -> bool:
        return not any((self.latency_ms, self.jitter_ms, self.noise_rad,
                        self.period_jitter_ms, self.lag_ms))  # fmt: skip

    @classmethod
    def paper(cls) -> ControllerModel:
        """Numbers shaped like the IRB120 paper's Table 5 (RTT 20..66 ms, mean 34; use a
        20 ms state period) and Table 4 (joint RMSE a few mrad)."""
        return cls(latency_ms=20.0, jitter_ms=6.8, noise_rad=0.004, period_jitter_ms=18.0,
                   lag_ms=30.0)  # fmt: skip

    def state_period_ms(self, rng: np.random.Generator, period_ms: float) -> float:
        """One state period: ``period_ms`` on average, ``period_jitter_ms`` its standard
        deviation, in the shape of the paper's Table 5 (0.5 to 63 ms around a 20.3 ms mean,
        median 15.7: many messages close behind the one before, a few after a long wait).
        That is a beta distribution on [:data:`PERIOD_SPAN`] x ``period_ms``; a deviation
        wider than that span allows is narrowed to fit."""
        lo, hi = (f * period_ms for f in PERIOD_SPAN)
        m = (period_ms - lo) / (hi - lo)
        var = min((self.period_jitter_ms / (hi - lo)) ** 2, 0.95 * m * (1 - m))
        if var <= 0.0:
            return period_ms
        n = m * (1 - m) / var - 1
        return lo + (hi - lo) * float(rng.beta(m * n, (1 - m) * n))


#: The span of a modelled state period, as fractions of its mean: the paper's Table 5 min
#: and max over its mean (0.5 and 63.5 ms, 20.3 ms).
PERIOD_SPAN = (0.5 / 20.3, 63.5 / 20.3)


class Executor:
    """Joint motion on the simulator clock (seconds). Not thread-safe: the controller's lock
    guards it.

    Knots ``(t, q)`` joined by cubic Hermite segments with their own start and end velocities.
    A trajectory whose first point is not skipped begins with an approach segment from rest to
    rest; the following points form one piece whose knot velocities are finite differences.
    """

    def __init__(self, model: RobotModel, q0: npt.ArrayLike) -> None:
        self.model = model
        q = np.asarray(q0, dtype=float)
        self._t: list[float] = [0.0]
        self._q: list[FloatArray] = [q]
        self._vs: list[FloatArray] = []  # start velocity of each segment
        self._ve: list[FloatArray] = []  # end velocity of each segment
        self._brk = 0  # index of the knot where the current piece starts
        self.trajectories = 0

    @property
    def end_time(self) -> float:
        return self._t[-1]

    def events(self) -> tuple[float, ...]:
        """The instants the current motion starts, reaches its first point, and ends."""
        if len(self._t) == 1:
            return ()
        return (self._t[0], self._t[self._brk], self._t[-1])

    def queued(self, t: float) -> int:
        """Points not yet reached at ``t``."""
        return len(self._t) - bisect.bisect_right(self._t, t)

    def moving(self, t: float) -> bool:
        return t < self._t[-1]

    def sample(self, t: float) -> FloatArray:
        """Joint positions (rad) at simulator time ``t``."""
        ts = self._t
        if t >= ts[-1] or len(ts) == 1:
            return np.array(self._q[-1])
        if t <= ts[0]:
            return np.array(self._q[0])
        i = bisect.bisect_right(ts, t) - 1
        h = ts[i + 1] - ts[i]
        s = (t - ts[i]) / h
        s2, s3 = s * s, s * s * s
        h00, h10 = 2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s
        h01, h11 = -2 * s3 + 3 * s2, s3 - s2
        q0, q1, v0, v1 = self._q[i], self._q[i + 1], self._vs[i], self._ve[i]
        return np.asarray(h00 * q0 + h10 * h * v0 + h01 * q1 + h11 * h * v1, dtype=float)

    def hold(self, t: float) -> None:
        """Stop where the arm is at ``t`` (STOP, or an empty activation)."""
        self._t, self._q, self._vs, self._ve, self._brk = [t], [self.sample(t)], [], [], 0

    def _duration(self, q: FloatArray, duration: float) -> float:
        step = float(np.max(np.abs(q - self._q[-1]) / self.model.max_speed))
        return max(duration, step, MIN_SEGMENT_S)

    def start(self, points: list[tuple[FloatArray, float]], t: float, skip_first: bool) -> None:
        """Run ``points`` (joints, duration) from time ``t``, pre-empting any motion. With
        ``skip_first``, a first point within 0.1 deg of the arm is skipped (RAPID)."""
        self.hold(t)
        self.trajectories += 1
        if not points:
            return
        q0, d0 = points[0]
        if not (skip_first and np.all(np.abs(q0 - self._q[0]) <= SKIP_TOLERANCE)):
            zero = np.zeros_like(q0)
            self._t.append(t + self._duration(q0, d0))
            self._q.append(np.asarray(q0, dtype=float))
            self._vs.append(zero)
            self._ve.append(zero)
            self._brk = 1
        self._append(points[1:])

    def extend(self, points: list[tuple[FloatArray, float]], t: float) -> None:
        """Append points after the last knot (streaming); an idle arm starts from ``t``."""
        if t >= self._t[-1]:
            self.hold(t)
        else:  # keep only the knots from the running segment on
            i = max(0, bisect.bisect_right(self._t, t) - 1)
            self._t, self._q = self._t[i:], self._q[i:]
            self._vs, self._ve = self._vs[i:], self._ve[i:]
            self._brk = max(0, self._brk - i)
        self._append(points)

    def _append(self, points: list[tuple[FloatArray, float]]) -> None:
        if not points:
            return
        old = len(self._t)
        for q, duration in points:
            self._t.append(self._t[-1] + self._duration(q, duration))
            self._q.append(np.asarray(q, dtype=float))
        b = self._brk
        v = np.gradient(np.array(self._q[b:]), np.array(self._t[b:]), axis=0, edge_order=1)
        for k in range(old - 1, len(self._t) - 1):  # the new segments, knot k -> k + 1
            start = self._ve[k - 1] if k > b else v[k - b]
            self._vs.append(start)
            self._ve.append(v[k + 1 - b])


@dataclass
class _Point:
    sequence: int
    joints: FloatArray
    velocity: float
    duration: float


class ArmController:
    """The controller: trajectory buffer, executor, state messages, one lock.

    ``clock()`` returns simulator seconds. ``byteorder``/``real`` pick the wire variant.
    """

    def __init__(self, model: RobotModel, *, profile: str = "abb", byteorder: sm.ByteOrder = "<",
                 real: sm.RealSize = 4, q0: npt.ArrayLike | None = None,
                 ctl_model: ControllerModel | None = None, clock: Callable[[], float],
                 seed: int = 0) -> None:  # fmt: skip
        if profile not in PROFILES:
            raise ValueError(f"unknown profile {profile!r}; expected one of {PROFILES}")
        self.model, self.profile, self.byteorder, self.real = model, profile, byteorder, real
        self.ctl = ctl_model or ControllerModel()
        self.clock = clock
        self.lock = threading.Lock()
        self.executor = Executor(model, model.work if q0 is None else q0)
        self.rng = np.random.default_rng(seed)
        self.buffer: list[_Point] = []
        self.dropped_points = 0
        self.points_received = 0
        self.rejected_points = 0
        self.frames_refused = 0
        self.stops = 0
        self.last_seq: int | None = None
        self._spec = sm.messages(byteorder, real)
        self._n = model.n_joints

    # ---------------------------------------------------------------- encoding helpers

    def encode(self, msg_type: int, comm: int, reply: int = 0, body: object = None) -> bytes:
        return sm.encode(msg_type, comm, reply, body,  # type: ignore[arg-type]
                         byteorder=self.byteorder, real=self.real)  # fmt: skip

    def _ack(self, reply: int = ReplyCode.SUCCESS, body: bytes | None = None) -> bytes:
        return self.encode(SimpleMessageType.JOINT_TRAJ_PT, CommType.SERVICE_REPLY, reply, body)

    # ---------------------------------------------------------------- motion port

    def motion_frame(self, link: Link, frame: bytes) -> bytes | None:
        """One frame on the motion port -> the reply, if any (called from the link thread)."""
        try:
            msg = sm.decode(frame, byteorder=self.byteorder, real=self.real)
        except ProtocolError as exc:
            log.warning("%s: undecodable frame dropped: %s", link.name, exc)
            return None
        if self.profile == "abb":
            return self._abb(link, msg, frame)
        return self._generic(msg, frame)

    def _point(self, body: object) -> _Point:
        assert isinstance(body, dict)
        q = np.asarray(body["joints"][: self._n], dtype=float)
        return _Point(int(body["sequence"]), q, float(body["velocity"]), float(body["duration"]))

    def _abb(self, link: Link, msg: sm.SimpleMessage, frame: bytes) -> bytes | None:
        size = self._spec.JointTrajPt.sizeof()
        raw = frame[sm.PREFIX_SIZE + sm.HEADER_SIZE :]
        if msg.msg_type != SimpleMessageType.JOINT_TRAJ_PT or len(raw) < size:
            # RAPID raises ERR_ARGVALERR / ERR_OUTOFBND: the task restarts, the socket closes
            self.frames_refused += 1
            log.warning("%s: ROS_motionServer error on msg_type %s (%d-byte body): the "
                        "server task restarts", link.name, int(msg.msg_type), len(raw))  # fmt: skip
            link.close()
            return None
        point = self._point(sm.plain(self._spec.JointTrajPt.parse(raw[:size])))
        with self.lock:
            self.points_received += 1
            self._abb_point(point)
        if msg.comm_type != CommType.SERVICE_REQUEST:
            return None
        self._delay()
        return self._ack()

    def _abb_point(self, p: _Point) -> None:
        if p.sequence == SpecialSeq.START_TRAJECTORY_DOWNLOAD:
            self.buffer = []
        if p.sequence == SpecialSeq.STOP_TRAJECTORY:
            self.buffer = []
            self._activate([])
            self.stops += 1
            return
        if len(self.buffer) < ABB_BUFFER:
            self.buffer.append(p)
        else:
            self.dropped_points += 1
            log.warning("ROS_motionServer: too many points (max %d), point %d dropped",
                        ABB_BUFFER, p.sequence)  # fmt: skip
        if p.sequence == SpecialSeq.END_TRAJECTORY:
            self._activate(self.buffer)
            self.buffer = []

    def _activate(self, points: list[_Point]) -> None:
        now = self.clock()
        log.info("ROS_motionServer: Sending %d points", len(points))
        self.executor.hold(now)
        if not points:
            return
        lo, hi = self.model.limits[:, 0] - 1e-6, self.model.limits[:, 1] + 1e-6
        for p in points:  # MoveAbsJ fails: ROS_motion.mod warns, aborts and restarts
            if not (
                np.all(np.isfinite(p.joints))
                and np.all((p.joints >= lo) & (p.joints <= hi))
                and math.isfinite(p.duration)
            ):
                self.rejected_points += 1
                log.warning("ROS_motion: point %d cannot be reached; trajectory aborted",
                            p.sequence)  # fmt: skip
                return
        start = now + self.ctl.lag_ms / 1000.0
        self.executor.start([(p.joints, p.duration) for p in points], start, skip_first=True)

    def _generic(self, msg: sm.SimpleMessage, frame: bytes) -> bytes | None:
        request = msg.comm_type == CommType.SERVICE_REQUEST
        if msg.comm_type == CommType.SERVICE_REPLY:
            return None  # REP-I0006: unsolicited replies are ignored
        if msg.msg_type == SimpleMessageType.PING:
            return self.encode(SimpleMessageType.PING, CommType.SERVICE_REPLY, ReplyCode.SUCCESS)
        if msg.msg_type != SimpleMessageType.JOINT_TRAJ_PT or not isinstance(msg.body, dict):
            if request:  # MessageManager: no handler -> header-only FAILURE of that type
                return self.encode(msg.msg_type, CommType.SERVICE_REPLY, ReplyCode.FAILURE)
            return None
        point = self._point(msg.body)
        with self.lock:
            self.points_received += 1
            ok = self._stream_point(point)
        if not request:
            return None
        self._delay()
        echo = frame[sm.PREFIX_SIZE + sm.HEADER_SIZE :]
        return self._ack(ReplyCode.SUCCESS if ok else ReplyCode.FAILURE, echo)

    def _stream_point(self, p: _Point) -> bool:
        now = self.clock()
        if p.sequence == SpecialSeq.STOP_TRAJECTORY:
            self.executor.hold(now)
            self.stops += 1
            self.last_seq = None
            return True
        lo, hi = self.model.limits[:, 0], self.model.limits[:, 1]
        bad = (
            p.sequence < 0
            or not (0.0 <= p.velocity <= 1.0)
            or not (math.isfinite(p.duration) and p.duration >= 0.0)
            or not bool(np.all(np.isfinite(p.joints)))
            or bool(np.any((p.joints < lo - 1e-6) | (p.joints > hi + 1e-6)))
        )
        last = self.last_seq
        in_order = p.sequence == 0 or (last is not None and p.sequence == last + 1)
        if p.sequence and self.executor.queued(now) >= MAX_QUEUE:
            self.rejected_points += 1
            return False  # the queue is full: the client retries later (MotoROS says BUSY)
        if bad or not in_order:
            self.rejected_points += 1
            if not in_order and not bad:  # REP-I0006: abort on an out-of-order sequence
                self.executor.hold(now)
                self.last_seq = None
            return False
        self.last_seq = p.sequence
        if p.sequence == 0:
            self.executor.start([(p.joints, p.duration)], now, skip_first=False)
        else:
            self.executor.extend([(p.joints, p.duration)], now)
        return True

    def _delay(self) -> None:
        c = self.ctl
        if c.latency_ms or c.jitter_ms:
            extra = float(self.rng.gamma(4.0, c.jitter_ms / 2.0)) if c.jitter_ms else 0.0
            time.sleep((c.latency_ms + extra) / 1000.0)

    # ---------------------------------------------------------------- state port

    def state_messages(self, t: float, feedback: bool) -> bytes:
        """JOINT_POSITION then STATUS (then JOINT_FEEDBACK with the controller time when
        ``feedback``) for simulator time ``t``."""
        if self.real == 4:  # the time on the wire is a float32: sample at exactly that time
            t = float(np.float32(t))
        with self.lock:
            q = self.executor.sample(t)
            moving = self.executor.moving(t)
        if self.ctl.noise_rad:
            q = q + self.rng.normal(0.0, self.ctl.noise_rad, q.shape)
        joints = [float(v) for v in q]
        topic = CommType.TOPIC
        out = [
            self.encode(SimpleMessageType.JOINT_POSITION, topic, 0,
                        {"sequence": 0, "joints": joints}),
            self.encode(SimpleMessageType.STATUS, topic, 0, {
                "drives_powered": 1, "e_stopped": 0, "error_code": 0, "in_error": 0,
                "in_motion": int(moving), "mode": 2, "motion_possible": 1,
            }),
        ]  # fmt: skip
        if feedback:
            out.append(self.encode(SimpleMessageType.JOINT_FEEDBACK, topic, 0, {
                "robot_id": 0, "valid_fields": 0x03, "time": t, "positions": joints,
                "velocities": [0.0] * sm.MAX_JOINTS, "accelerations": [0.0] * sm.MAX_JOINTS,
            }))  # fmt: skip
        return b"".join(out)


class MotionSession:
    """One motion-port link (serving-layer session)."""

    def __init__(self, controller: ArmController, link: Link) -> None:
        self.controller, self.link = controller, link

    def on_frame(self, frame: bytes, now: float) -> bytes | None:
        return self.controller.motion_frame(self.link, frame)

    def on_close(self) -> None:
        # the RAPID task re-listens; an activated trajectory keeps running (ROS_motion.mod),
        # only the points not yet activated are lost
        with self.controller.lock:
            self.controller.buffer = []
        log.info("%s: motion client gone; an activated trajectory runs on", self.link.name)


class StateSession:
    """One state-port link: the state server never reads its socket."""

    def __init__(self, controller: ArmController, link: Link) -> None:
        self.controller, self.link = controller, link

    def on_frame(self, frame: bytes, now: float) -> bytes | None:
        return None

    def on_close(self) -> None:
        log.info("%s: state client gone", self.link.name)
