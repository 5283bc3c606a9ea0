"""Industrial arms over ROS-Industrial Simple Message: the ABB IRB120 first.

>>> with Arm.connect("192.168.125.1") as arm:              # doctest: +SKIP
...     arm.wait_for_state()
...     arm.download(circle(load_model("irb120")))    # -1, points, -3: the ABB way
...     arm.wait_until_idle(60)

Two links, each a :class:`~robocli.devices.session.Session`: the **motion** port (11000), where
each JOINT_TRAJ_PT is a SERVICE_REQUEST whose SERVICE_REPLY is awaited with a timeout, and the
**state** port (11002), whose JOINT_POSITION / STATUS / JOINT_FEEDBACK messages become
timestamped :class:`JointSample` and :class:`ArmStatus` values (a bounded history). Either
port may be used alone. The client never sends PING or GET_VERSION: an ABB motion server
accepts JOINT_TRAJ_PT only.

Download (:meth:`Arm.download`): sequence -1, the points, -3; the ABB server keeps 100 points
and silently drops the rest, so longer trajectories are refused before anything is sent
unless ``split=True``. Streaming (:meth:`Arm.stream`): points 0..N-1 for servers that execute
as they receive (industrial_robot_client's streamer); an ABB never executes them. A FAILURE
reply raises :class:`~robocli.errors.DeviceError`. :meth:`Arm.close` sends STOP (-4) when a
trajectory runs, unless told not to. A motion link lost while a trajectory this client
activated may run (the last point, -3, went out but its acknowledgement never came) raises a
:class:`~robocli.errors.ConnectionLost` that says the arm may be moving, after one try to
reconnect and send STOP over the new connection (its outcome is in the message).
:attr:`Arm.alive` and :meth:`Arm.check` tell whether a link was lost (a quiet motion port
included) without waiting.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable
from types import TracebackType
from typing import Any

import numpy as np
import numpy.typing as npt

from robocli.devices.arm.link import open_session, point_frame, stop_frame
from robocli.devices.arm.state import (
    ABB_MAX_POINTS,
    ArmStatus,
    JointSample,
    Point,
    Recorder,
    prepare,
    split_points,
)
from robocli.devices.session import FrameListener, Listeners, Session
from robocli.errors import (
    EXIT_FAILURE,
    ConnectionLost,
    DeviceError,
    InvalidArgument,
    ProtocolError,
    RobocliError,
    TimeoutError,
    TransportError,
)
from robocli.io.trajlog import TrajectoryLog
from robocli.kinematics import load_model
from robocli.kinematics.model import RobotModel
from robocli.protocols import simple_message as sm
from robocli.protocols.common import find_refusal
from robocli.protocols.simple_message import CommType, MsgType, ReplyCode, SpecialSeq

__all__ = ["Arm", "SampleListener", "StillMoving"]

log = logging.getLogger("robocli.devices.arm")

#: Called with each decoded joint sample (in the state reader's thread).
SampleListener = Callable[[JointSample], None]

_POS = sm.ValidFields.POSITION
_JOINT_TYPES = (MsgType.JOINT_POSITION, MsgType.JOINT_FEEDBACK, MsgType.STATUS)
_ORDERS = {"little": "<", "big": ">", "<": "<", ">": ">"}


class StillMoving(TimeoutError):
    """:meth:`Arm.wait_until_idle` gave up while the states still show the trajectory
    running: the controller answers (not an unreachable one: exit 1), the arm moves on."""

    exit_code = EXIT_FAILURE


class Arm:
    """A connected arm controller. Make one with :meth:`connect`; use it as a context manager.

    ``robot``: the :class:`~robocli.kinematics.model.RobotModel` limits are checked against.
    ``history``: joint samples kept (oldest dropped).
    """

    def __init__(self, motion: Session | None, state: Session | None, *, robot: RobotModel,
                 byteorder: sm.ByteOrder, real: sm.RealSize, timeout: float,
                 history: int = 10_000) -> None:  # fmt: skip
        """Use :meth:`connect`."""
        self.robot, self.byteorder, self.real, self.timeout = robot, byteorder, real, timeout
        self._motion, self._state = motion, state
        self.history: deque[JointSample] = deque(maxlen=history)
        self.status: ArmStatus | None = None  #: the last STATUS received
        self.joints: JointSample | None = None  #: the last joint sample received
        self._cond = threading.Condition()
        self._statuses = 0
        stats = (state or motion).stats  # type: ignore[union-attr]
        self._sample_listeners: Listeners[SampleListener] = Listeners(stats, "arm samples")
        self._activated_at: float | None = None  # monotonic time of the last activation
        self._expected_end = 0.0
        self._target: tuple[float, ...] | None = None  # last point of the activated trajectory
        self._moved = False  # a STATUS received since the activation said in motion
        self._start: tuple[float, ...] | None = None  # joints when it was activated
        self._streamed = False  # the activated trajectory was streamed (not downloaded)
        self._travel = 0.0  # how far (rad) its points lie from the start at most
        self._displaced = False  # a joint sample since the activation was away from the start
        self._stop_frame = stop_frame(robot, byteorder, real)
        #: (host, port) of the motion server, to reconnect and STOP after a lost link
        self.motion_address: tuple[str, int] | None = None
        for session, handler in ((motion, self._on_motion_frame), (state, self._on_state_frame)):
            if session is not None:
                session.on_frame = handler

    # ------------------------------------------------------------------ connecting

    @classmethod
    def connect(cls, host: str, motion_port: int = sm.PORT_MOTION,
                state_port: int = sm.PORT_STATE, *, byte_order: str = "little",
                real_size: int = 4, robot: str | RobotModel = "irb120", motion: bool = True,
                state: bool = True, timeout: float = 5.0, history: int = 10_000,
                listeners: Iterable[FrameListener] = (),
                stop_on_failure: bool = True) -> Arm:  # fmt: skip
        """Open the motion and/or state port of the controller at ``host``.

        ``byte_order``: ``"little"`` (ABB) or ``"big"`` (Fanuc, FS100); ``real_size`` 4 or 8.
        With ``state``, waits up to ``timeout`` s for the first state message. A motion link
        that fails sends STOP (-4) on its way down unless ``stop_on_failure=False`` (an
        observer such as ``dump arm``, which never sends anything). Raises
        :class:`TransportError` (unreachable, or a port answering another protocol),
        :class:`DeviceError` (the controller refused: another client holds the port),
        :class:`InvalidArgument` (bad option), an unknown-model error (exit 2).
        """
        order = _ORDERS.get(byte_order)
        if order is None:
            raise InvalidArgument(f"byte_order must be 'little' or 'big', not {byte_order!r}")
        if real_size not in (4, 8):
            raise InvalidArgument(f"real_size must be 4 or 8, not {real_size!r}")
        if not (motion or state):
            raise InvalidArgument("connect to the motion port, the state port, or both")
        model = robot if isinstance(robot, RobotModel) else load_model(robot)
        sessions: list[Session] = []
        try:
            links: list[Session | None] = []
            real: sm.RealSize = real_size  # type: ignore[assignment]
            wire: sm.ByteOrder = order  # type: ignore[assignment]
            stop = [stop_frame(model, wire, real)] if stop_on_failure else []
            ports = ((motion, motion_port, "motion"), (state, state_port, "state"))
            for wanted, port, name in ports:
                link = open_session(host, port, name, wire, real, timeout,
                             stop if name == "motion" else []) if wanted else None  # fmt: skip
                links.append(link)
                sessions += [link] if link is not None else []
            arm = cls(links[0], links[1], robot=model, byteorder=wire, real=real, timeout=timeout,
                      history=history)  # fmt: skip
            arm.motion_address = (host, motion_port) if motion else None
            for listener in listeners:
                arm.add_listener(listener)
            if arm._state is not None:
                arm._first_state(timeout)
            if arm._motion is not None:  # (after the state's first message: no extra wait)
                arm._no_refusal(0.01 if arm._state is not None else 0.1)
            for s in sessions:
                s.start()
            if arm._motion is not None:
                arm._motion.close_timeout = 2.0
            return arm
        except BaseException:
            for s in sessions:
                s.close()
            raise

    def _first_state(self, timeout: float) -> None:
        """Read until the first valid state message (before the reader starts, so that a
        refusal line or another protocol is seen)."""
        s = self._state
        assert s is not None
        url = s.transport.url
        wrong = TransportError(f"{url}: the port answers, but not in Simple Message "
                               "(another protocol, or the wrong byte order or real size)")
        try:
            s.request(None, lambda f: True, timeout)
            # a stream in the other byte order frames 3 bytes late (small ints even decode)
            if s.stats.dropped_bytes or s.stats.decode_errors:
                raise wrong
        except ConnectionLost:
            reason = find_refusal(s.raw_tail())
            if reason is not None:
                raise DeviceError(f"{url}: {reason}") from None
            raise
        except TimeoutError:
            if s.raw_tail() or s.stats.decode_errors:
                raise wrong from None
            raise TimeoutError(f"{url}: no state message within {timeout:g} s") from None

    def _no_refusal(self, wait: float) -> None:
        """Raise :class:`DeviceError` when the motion port refused this client (a busy
        server says why on connecting, then closes): its motion port is quiet otherwise, so
        read what came within ``wait`` s before the reader starts (and would swallow it)."""
        s = self._motion
        assert s is not None
        try:
            s.request(None, lambda f: False, wait)
        except TimeoutError:
            return  # nothing said: a controller's motion port speaks only when spoken to
        except RobocliError:
            reason = find_refusal(s.raw_tail())
            if reason is not None:
                raise DeviceError(f"{s.transport.url}: {reason}") from None
            raise

    @property
    def alive(self) -> bool:
        """True while every link this Arm opened is up: none failed (a dropped connection, a
        decoding error) and :meth:`close` was not called. Never blocks."""
        return all(s.alive for s in self._sessions("both"))

    def check(self) -> None:
        """Return while :attr:`alive`; else raise the error that ended a link (a
        :class:`ConnectionLost` for a dropped connection or once closed, a
        :class:`ProtocolError` for bytes that did not decode). Never blocks."""
        for s in self._sessions("both"):
            s.check()

    def close(self, stop: bool = True) -> None:
        """Close both links. With ``stop`` (the default) a trajectory that may be running is
        stopped first (STOP, -4); ``stop=False`` leaves it running, as a dropped link does on
        an ABB. Bounded in time; idempotent."""
        if self._motion is not None:
            seq = [self._stop_frame] if stop and self.running() else []
            self._motion.close(seq)
        if self._state is not None:
            self._state.close()
        with self._cond:
            self._cond.notify_all()

    def __enter__(self) -> Arm:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:  # fmt: skip
        self.close()

    # ------------------------------------------------------------------ listeners

    def add_listener(self, listener: FrameListener, ports: str = "both") -> None:
        """Call ``listener(direction, frame, t)`` for every frame sent ("tx") or received
        ("rx") on the ``"motion"``, ``"state"`` or ``"both"`` ports. A listener that raises
        is logged once, counted in ``stats.listener_errors``, and never stops the client."""
        for s in self._sessions(ports):
            s.listeners.add(listener)

    def remove_listener(self, listener: FrameListener, ports: str = "both") -> None:
        for s in self._sessions(ports):
            s.listeners.remove(listener)

    def add_sample_listener(self, listener: SampleListener) -> None:
        """Call ``listener(sample)`` for each :class:`JointSample` (isolated like frames)."""
        self._sample_listeners.add(listener)

    def remove_sample_listener(self, listener: SampleListener) -> None:
        self._sample_listeners.remove(listener)

    def _sessions(self, ports: str) -> list[Session]:
        if ports not in ("both", "motion", "state"):
            raise InvalidArgument(f"ports must be 'motion', 'state' or 'both', not {ports!r}")
        picked = [(self._motion, "motion"), (self._state, "state")]
        return [s for s, name in picked if s is not None and ports in ("both", name)]

    @property
    def stats(self) -> dict[str, Any]:
        """Counters of both links (JSON-ready)."""
        return {name: s.stats.as_dict() for s, name in
                ((self._motion, "motion"), (self._state, "state")) if s is not None}  # fmt: skip

    # ------------------------------------------------------------------ state

    def _on_state_frame(self, frame: bytes, t: float) -> None:
        msg = sm.decode(frame, byteorder=self.byteorder, real=self.real)
        body = msg.body
        if not isinstance(body, dict):
            if isinstance(body, bytes) and msg.msg_type in _JOINT_TYPES:
                name = MsgType(msg.msg_type).name
                raise ProtocolError(f"{name} with a {len(body)}-byte body: not {self.real}-byte "
                                    "reals (the wrong real size?)")
            return
        n = self.robot.n_joints
        sample = None
        if msg.msg_type == MsgType.JOINT_POSITION:
            sample = JointSample(t, tuple(body["joints"][:n]))
        elif msg.msg_type == MsgType.JOINT_FEEDBACK and body["valid_fields"] & _POS:
            rt = body["time"] if body["valid_fields"] & sm.ValidFields.TIME else None
            sample = JointSample(t, tuple(body["positions"][:n]), rt, "joint_feedback")
        elif msg.msg_type == MsgType.STATUS:
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
            if (self._activated_at is not None and t > self._activated_at
                    and self._start is not None and _gap(sample.joints, self._start) > 1e-3):
                self._displaced = True
            self._cond.notify_all()
        if len(self._sample_listeners):
            self._sample_listeners.notify(sample)

    def wait_for_state(self, timeout: float | None = None) -> JointSample:
        """The next joint sample (raises :class:`TimeoutError`, or the link's error)."""
        s = self._need(self._state, "state")
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
        s = self._need(self._state, "state")
        since = self._activated_at if self._activated_at is not None else time.monotonic()
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

    def record(self, max_samples: int = 720_000) -> Recorder:
        """Start recording joint samples (a :class:`Recorder`; stop it for the log). At most
        ``max_samples`` are kept, the oldest dropped first (about 350 bytes each; the default
        holds an hour of 100 Hz state with JOINT_FEEDBACK)."""
        return Recorder(self, max_samples)

    # ------------------------------------------------------------------ motion

    def _point_frame(self, seq: int, p: Point) -> bytes:
        return point_frame(seq, p, self.byteorder, self.real)

    def _on_motion_frame(self, frame: bytes, t: float) -> None:
        sm.decode(frame, byteorder=self.byteorder, real=self.real)  # unsolicited: checked only

    def send_point(self, sequence: int, joints: npt.ArrayLike, *, velocity: float = 0.0,
                   duration: float = 0.0, timeout: float | None = None) -> float:
        """Send one JOINT_TRAJ_PT as a SERVICE_REQUEST and wait for its SERVICE_REPLY; returns
        the round trip in seconds (what the paper's Table 5 measured). No model check: an
        ABB enqueues the point (``sequence`` -1 resets its buffer, -3 activates, -4 stops).
        Raises :class:`DeviceError` on FAILURE, :class:`TimeoutError` after ``timeout``."""
        q = tuple(float(v) for v in np.asarray(joints, dtype=float).ravel())
        start = time.perf_counter()
        self._send_point(int(sequence), Point(q, float(velocity), float(duration)),
                         self.timeout if timeout is None else timeout)  # fmt: skip
        return time.perf_counter() - start

    def _is_reply(self, frame: bytes) -> bool:
        """A JOINT_TRAJ_PT SERVICE_REPLY (the acknowledgement of a point)."""
        try:
            m = sm.decode(frame, byteorder=self.byteorder, real=self.real)
        except ProtocolError:
            return False
        return m.msg_type == MsgType.JOINT_TRAJ_PT and m.comm_type == CommType.SERVICE_REPLY

    def _send_point(self, seq: int, p: Point, timeout: float) -> None:
        s = self._need(self._motion, "motion")
        order, real, is_reply = self.byteorder, self.real, self._is_reply
        before = s.stats.decode_errors
        try:
            reply = s.request(self._point_frame(seq, p), is_reply, timeout)
        except TimeoutError:
            if s.stats.decode_errors != before:
                raise TransportError(f"{s.transport.url}: the motion port answers, but not in "
                                     "Simple Message (another protocol?)") from None
            raise TimeoutError(f"{s.transport.url}: no reply to point {seq} within "
                               f"{timeout:g} s") from None
        except ConnectionLost as exc:
            reason = find_refusal(s.raw_tail())
            if reason:
                raise DeviceError(f"{s.transport.url}: {reason}") from None
            if self.running():  # what went out may have started the arm
                raise self._lost_while_moving(s, seq, exc) from None
            raise exc from None
        code = sm.decode(reply, byteorder=order, real=real).reply_code
        if code != ReplyCode.SUCCESS:
            raise DeviceError(f"{s.transport.url}: the controller refused point {seq} "
                              f"(reply code {int(code)}: FAILURE)", code=int(code))  # fmt: skip

    def check_trajectory(self, traj: TrajectoryLog | tuple[npt.ArrayLike, npt.ArrayLike], *,
                         split: bool = False) -> None:  # fmt: skip
        """The checks :meth:`download` makes before sending anything (finite values,
        increasing times, joint ranges and speeds, the 100-point buffer unless ``split``;
        :meth:`stream` has no such buffer), without sending: call it before moving the arm
        to a trajectory's start."""
        self._checked(traj, split, None, None)

    def _checked(
        self, traj: TrajectoryLog | tuple[npt.ArrayLike, npt.ArrayLike], split: bool,
        q_now: npt.ArrayLike | None, first_duration: float | None,
    ) -> list[Point]:  # fmt: skip
        points = prepare(self.robot, traj, q_now, first_duration)
        if len(points) > ABB_MAX_POINTS and not split:
            raise InvalidArgument(
                f"trajectory has {len(points)} points; the ABB server keeps {ABB_MAX_POINTS} "
                "and silently drops the rest (use split=True / --split)")
        return points

    def download(self, traj: TrajectoryLog | tuple[npt.ArrayLike, npt.ArrayLike], *,
                 split: bool = False, first_duration: float | None = None,
                 timeout: float | None = None,
                 progress: Callable[[int, int], None] | None = None) -> int:  # fmt: skip
        """Upload ``traj`` the ABB way: -1, points, -3 (activates), each acknowledged.

        Checked first against the robot model (finite, increasing times, ranges, speeds) and
        the 100-point buffer (``split=True`` uploads several trajectories in turn, waiting for
        each to finish: needs the state port). ``progress(done, total)`` after each ack.
        Returns the number of points sent. Raises :class:`InvalidArgument` /
        ``LimitError`` before sending anything, :class:`DeviceError` on a FAILURE reply,
        :class:`TimeoutError` when a reply does not come within ``timeout`` s.
        """
        points = self._checked(traj, split, self._q_now(), first_duration)
        chunks = split_points(points)
        if len(chunks) > 1:
            self._need(self._state, "state")
        wait = self.timeout if timeout is None else timeout
        total, done = sum(len(c) + (len(c) == 1) for c in chunks), 0
        for k, chunk in enumerate(chunks):
            if k:
                self.wait_until_idle(sum(p.duration for p in chunks[k - 1]) * 4 + 30)
            if len(chunk) == 1:
                chunk = chunk * 2  # industrial_robot_client duplicates single points
            for i, p in enumerate(chunk):
                last = i == len(chunk) - 1
                seq = SpecialSeq.START_TRAJECTORY_DOWNLOAD if i == 0 else (
                    SpecialSeq.END_TRAJECTORY if last else i)
                if last:
                    self._activated(chunk)
                self._send_point(seq, p, wait)
                done += 1
                if progress is not None:
                    progress(done, total)
        return done

    def move_to(self, joints: npt.ArrayLike, duration: float | None = None,
                timeout: float | None = None) -> int:
        """Download a move from where the arm is (needs the state port) to ``joints`` (rad),
        taking ``duration`` s (default: a quarter of the speed limits, at least 0.5 s)."""
        self._need(self._state, "state")
        here = self.wait_for_state(timeout).joints
        goal = np.asarray(joints, dtype=float)
        if duration is None:
            gap = np.abs(goal - np.asarray(here)) / (0.25 * self.robot.max_speed)
            duration = max(0.5, float(np.max(gap)))
        path = (np.array([0.0, duration]), np.array([here, goal]))
        return self.download(path, first_duration=0.1,
                             timeout=timeout)  # fmt: skip

    def stream(self, traj: TrajectoryLog | tuple[npt.ArrayLike, npt.ArrayLike], *,
               first_duration: float | None = None, timeout: float | None = None,
               progress: Callable[[int, int], None] | None = None) -> int:  # fmt: skip
        """Send ``traj`` point by point (sequence 0..N-1), each acknowledged before the next,
        to a streaming server (not an ABB: it never executes points without -3)."""
        points = prepare(self.robot, traj, self._q_now(), first_duration)
        wait = self.timeout if timeout is None else timeout
        self._activated(points, streamed=True)
        for i, p in enumerate(points):
            self._send_point(i, p, wait)
            if progress is not None:
                progress(i + 1, len(points))
        return len(points)

    def _lost_while_moving(self, s: Session, seq: int, exc: ConnectionLost) -> ConnectionLost:
        """The motion link was lost while a trajectory this client activated may run (the
        last point, -3, went out but no acknowledgement came back): the arm may be moving.
        Reconnect once and send STOP (-4); the error says what came of it."""
        url = s.transport.url
        what = "the last point (-3)" if seq == SpecialSeq.END_TRAJECTORY else f"point {seq}"
        head = (f"{url}: {str(exc).removeprefix(f'{url}: ')} after {what} went out, before "
                "its acknowledgement: the arm may be moving")  # fmt: skip
        log.warning("%s; reconnecting to send STOP (-4)", head)
        try:
            self._stop_over_new_link()
        except RobocliError as why:
            return ConnectionLost(f"{head}, and STOP (-4) could not be sent over a new "
                                  f"connection ({str(why).removeprefix(f'{url}: ')}): stop it "
                                  "at the controller")  # fmt: skip
        self._activated_at, self._expected_end, self._target = None, 0.0, None
        return ConnectionLost(f"{head}: STOP (-4) sent over a new connection, and "
                              "acknowledged")  # fmt: skip

    def _stop_over_new_link(self) -> None:
        """Open a new motion link, send STOP (-4), wait for its acknowledgement (within
        ``timeout`` s in all), close the link. Raises what went wrong."""
        if self.motion_address is None:
            raise ConnectionLost("the motion server's address is unknown")
        host, port = self.motion_address
        deadline = time.monotonic() + self.timeout
        try:
            link = open_session(host, port, "motion", self.byteorder, self.real, self.timeout,
                                [])  # fmt: skip
        except TransportError as exc:  # "cannot connect to URL: connection refused (hint)"
            text = str(exc)
            raise TransportError((text.partition(": ")[2] or text).partition(" (")[0]) from None
        try:
            try:
                left = max(0.05, deadline - time.monotonic())
                reply = link.request(self._stop_frame, self._is_reply, left)
            except ConnectionLost:
                reason = find_refusal(link.raw_tail())
                if reason:
                    raise DeviceError(reason) from None
                raise
            code = sm.decode(reply, byteorder=self.byteorder, real=self.real).reply_code
            if code != ReplyCode.SUCCESS:
                raise DeviceError(f"the controller refused STOP (reply code {int(code)})",
                                  code=int(code))  # fmt: skip
        finally:
            link.close()

    def stop(self, timeout: float | None = None) -> None:
        """STOP (-4): abort the running trajectory, acknowledged within ``timeout`` s."""
        self.send_point(SpecialSeq.STOP_TRAJECTORY, (0.0,) * self.robot.n_joints,
                        timeout=timeout)
        self._activated_at, self._expected_end, self._target = None, 0.0, None

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
            self._travel = max((_gap(p.joints, start) for p in points),
                               default=0.0) if start is not None else 0.0  # fmt: skip

    def _q_now(self) -> tuple[float, ...] | None:
        sample = self.joints
        return sample.joints if sample is not None else None

    @staticmethod
    def _need(session: Session | None, name: str) -> Session:
        if session is None:
            raise InvalidArgument(f"this Arm was connected without its {name} port")
        session.check()
        return session


def _gap(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    """Largest joint difference (rad)."""
    return max(abs(x - y) for x, y in zip(a, b, strict=False))
