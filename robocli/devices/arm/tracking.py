"""What the state port says about the arm, kept and waited on: the joint samples and the
last STATUS, the waits on them (:meth:`~StateTracking.wait_for_state`,
:meth:`~StateTracking.wait_until_idle`), and whether the trajectory this client activated
may still run (:meth:`~StateTracking.running`).

Part of the arm client: :class:`~robocli.devices.arm.client.Arm` inherits
:class:`StateTracking` (through :class:`~robocli.devices.arm.motion.Motion`), which holds
these methods and the attributes they share.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable

from robocli.devices.arm.link import need
from robocli.devices.arm.state import ArmStatus, JointRecorder, JointSample, Point
from robocli.devices.session import LinkStats, Listeners, Session
from robocli.errors import EXIT_FAILURE, DeviceError, ProtocolError, TimeoutError
from robocli.kinematics.model import RobotModel
from robocli.protocols import simple_message as sm
from robocli.protocols.simple_message import SimpleMessageType

__all__ = ["SampleListener", "StateTracking", "StillMoving"]

#: Called with each decoded joint sample (in the state reader's thread).
SampleListener = Callable[[JointSample], None]

_POS = sm.ValidFields.POSITION
_JOINT_TYPES = (
    SimpleMessageType.JOINT_POSITION,
    SimpleMessageType.JOINT_FEEDBACK,
    SimpleMessageType.STATUS,
)


class StillMoving(TimeoutError):
    """:meth:`Arm.wait_until_idle` gave up while the states still show the trajectory
    running: the controller answers (not an unreachable one: exit 1), the arm moves on."""

    exit_code = EXIT_FAILURE


class StateTracking:
    """The state port's samples and statuses, and the activated trajectory's progress."""

    def __init__(self, state: Session | None, stats: LinkStats, *, robot: RobotModel,
                 byteorder: sm.ByteOrder, real: sm.RealSize, timeout: float,
                 history: int) -> None:  # fmt: skip
        """``stats``: the counters sample listeners' errors go to."""
        self.robot, self.byteorder, self.real, self.timeout = robot, byteorder, real, timeout
        self._state = state
        self.history: deque[JointSample] = deque(maxlen=history)
        self.status: ArmStatus | None = None  #: the last STATUS received
        self.joints: JointSample | None = None  #: the last joint sample received
        self._cond = threading.Condition()
        self._statuses = 0
        self._sample_listeners: Listeners[SampleListener] = Listeners(stats, "arm samples")
        self._activated_at: float | None = None  # monotonic time of the last activation
        self._expected_end = 0.0
        self._target: tuple[float, ...] | None = None  # last point of the activated trajectory
        self._moved = False  # a STATUS received since the activation said in motion
        self._start: tuple[float, ...] | None = None  # joints when it was activated
        self._streamed = False  # the activated trajectory was streamed (not downloaded)
        self._sent_all_at: float | None = None  # when its last point was acknowledged
        self._travel = 0.0  # how far (rad) its points lie from the start at most
        self._displaced = False  # a joint sample since the activation was away from the start

    def _on_state_frame(self, frame: bytes, t: float) -> None:
        msg = sm.decode(frame, byteorder=self.byteorder, real=self.real)
        body = msg.body
        if not isinstance(body, dict):
            if isinstance(body, bytes) and msg.msg_type in _JOINT_TYPES:
                name = SimpleMessageType(msg.msg_type).name
                raise ProtocolError(
                    f"{name} with a {len(body)}-byte body: not {self.real}-byte "
                    "reals (the wrong real size?)"
                )
            return
        n = self.robot.n_joints
        sample = None
        if msg.msg_type == SimpleMessageType.JOINT_POSITION:
            sample = JointSample(t, tuple(body["joints"][:n]))
        elif msg.msg_type == SimpleMessageType.JOINT_FEEDBACK and body["valid_fields"] & _POS:
            rt = body["time"] if body["valid_fields"] & sm.ValidFields.TIME else None
            sample = JointSample(t, tuple(body["positions"][:n]), rt, "joint_feedback")
        elif msg.msg_type == SimpleMessageType.STATUS:
            with self._cond:
                self.status = ArmStatus.from_body(body, t)
                self._statuses += 1
                if self.status.in_motion and self._activated_at is not None:
                    self._moved = self._moved or t > self._activated_at
                self._cond.notify_all()
            return
        if sample is None:
            return
        with self._cond:
            self.history.append(sample)
            self.joints = sample
            if (
                self._activated_at is not None
                and t > self._activated_at
                and self._start is not None
                and _gap(sample.joints, self._start) > 1e-3
            ):
                self._displaced = True
            self._cond.notify_all()
        if len(self._sample_listeners):
            self._sample_listeners.notify(sample)

    def wait_for_state(self, timeout: float | None = None) -> JointSample:
        """The next joint sample (raises :class:`TimeoutError`, or the link's error)."""
        s = need(self._state, "state")
        deadline = time.monotonic() + (self.timeout if timeout is None else timeout)
        with self._cond:
            count = len(self.history)
            seen = self.joints
            while self.joints is seen or (self.joints is None and len(self.history) == count):
                s.check()
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(f"{s.transport.url}: no state within the timeout")
                self._cond.wait(min(left, 0.1))
            assert self.joints is not None
            return self.joints

    def _finished(self, st: ArmStatus) -> bool:
        """``st`` (received after the activation) shows the activated trajectory done: not
        in motion, and either seen moving since, or at its last point (a state sampled
        before the activation may be received after it)."""
        if st.in_motion:
            return False
        if self._streamed:  # idle between two streamed points is not the end: only a STATUS
            # received once every point was acknowledged, with the arm at the last one
            done = self._sent_all_at is not None and st.t > self._sent_all_at
            sample = self.joints
            return (done and self._target is not None and sample is not None
                    and _gap(sample.joints, self._target) < 1e-3)  # fmt: skip
        if self._moved or self._target is None:
            return True
        sample = self.joints
        return (self._start is not None and sample is not None
                and _gap(self._start, self._target) > 1e-3  # (a closed path ends where it began)
                and _gap(sample.joints, self._target) < 1e-3)  # fmt: skip

    def running(self) -> bool:
        """True while a trajectory this client activated may still run: the states since do
        not show it finished (without the state port: its nominal end has not passed)."""
        if self._activated_at is None:
            return False
        st = self.status
        if self._state is not None and st is not None and st.t > self._activated_at:
            return not self._finished(st)
        return time.monotonic() < self._expected_end

    def wait_until_idle(self, timeout: float, settle: float = 2.0) -> ArmStatus:
        """Wait until the states show the arm idle: not in motion after it was seen moving
        since the last activation, or at the trajectory's last point, or (a trajectory the
        controller refused) not in motion for ``settle`` s. Needs the state port. Raises
        :class:`StillMoving` (a :class:`TimeoutError`) when the states still show motion
        after ``timeout`` s (nothing is stopped), :class:`TimeoutError` when no STATUS came."""
        s = need(self._state, "state")
        since = self._activated_at if self._activated_at is not None else time.monotonic()
        if self._streamed and self._sent_all_at is not None:  # idle before the last point
            since = max(since, self._sent_all_at)  # was acknowledged is no end of it
        deadline = time.monotonic() + timeout
        with self._cond:
            count = self._statuses
            while True:
                s.check()
                st = self.status
                if self._statuses != count and st is not None and st.t > since:
                    count = self._statuses
                    if self._activated_at is None and not st.in_motion:
                        return st
                    if self._finished(st) or (not st.in_motion and st.t - since >= settle):
                        if not self._stalled():
                            return st
                        if time.monotonic() >= self._expected_end:
                            raise DeviceError(
                                f"{s.transport.url}: the controller acknowledged the streamed "
                                "points, but the arm did not move while their durations "
                                "elapsed (an ABB never runs streamed points: download them, "
                                "without --stream)")  # fmt: skip
                left = deadline - time.monotonic()
                if left <= 0:
                    if st is None or st.t <= since:
                        raise TimeoutError(f"{s.transport.url}: no STATUS within {timeout:g} s")
                    raise StillMoving(f"{s.transport.url}: the trajectory has not ended after "
                                      f"{timeout:g} s")  # fmt: skip
                self._cond.wait(min(left, 0.1))

    def _stalled(self) -> bool:
        """The activated trajectory was streamed and should move the arm, but no state since
        showed motion or a joint away from where it began."""
        return (self._streamed and self._travel > 1e-3 and not self._moved
                and not self._displaced)  # fmt: skip

    def record(self, max_samples: int = 720_000) -> JointRecorder:
        """Start recording joint samples (a :class:`JointRecorder`; stop it for the log). At most
        ``max_samples`` are kept, the oldest dropped first (about 350 bytes each; the default
        holds an hour of 100 Hz state with JOINT_FEEDBACK)."""
        return JointRecorder(self, max_samples)

    def _streamed_all(self) -> None:
        """Every point of the streamed trajectory is acknowledged: from now on a STATUS
        saying idle may be its end (before, it may be the gap before a point still coming)."""
        with self._cond:
            self._sent_all_at = time.monotonic()

    def _activated(self, points: list[Point], streamed: bool = False) -> None:
        now = time.monotonic()
        start = self.joints.joints if self.joints is not None else None
        with self._cond:
            self._activated_at = now
            self._expected_end = now + sum(p.duration for p in points) + 1.0
            self._target = points[-1].joints if points else None
            self._start = start
            self._moved = self._displaced = False
            self._streamed = streamed
            self._sent_all_at = None if streamed else now  # a download is sent whole here
            self._travel = max((_gap(p.joints, start) for p in points),
                               default=0.0) if start is not None else 0.0  # fmt: skip


def _gap(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    """Largest joint difference (rad)."""
    return max(abs(x - y) for x, y in zip(a, b, strict=False))
