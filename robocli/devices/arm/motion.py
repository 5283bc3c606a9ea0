"""The motion port: one point and its acknowledgement, a trajectory's download (the ABB
way: -1, the points, -3) or stream (0..N-1), STOP (-4), and the recovery when the motion link
is lost while a trajectory this client activated may run (reconnect once and send STOP).

Part of the arm client: :class:`~robocli.devices.arm.client.Arm` inherits :class:`Motion`,
which holds these methods and the motion link's attributes (beyond those of
:class:`~robocli.devices.arm.tracking.StateTracking`, its base).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from robocli.devices.arm.link import need, open_session, point_frame, stop_frame
from robocli.devices.arm.state import ABB_MAX_POINTS, Point, prepare, split_points
from robocli.devices.arm.tracking import StateTracking
from robocli.devices.session import Session
from robocli.errors import (
    ConnectionLost,
    DeviceError,
    InvalidArgument,
    ProtocolError,
    RobocliError,
    TimeoutError,
    TransportError,
)
from robocli.kinematics.model import RobotModel
from robocli.kinematics.trajlog import TrajectoryLog
from robocli.protocols import simple_message as sm
from robocli.protocols.common import find_refusal
from robocli.protocols.simple_message import CommType, ReplyCode, SimpleMessageType, SpecialSeq

__all__ = ["Motion"]

log = logging.getLogger("robocli.devices.arm")


class Motion(StateTracking):
    """Points, trajectories and STOP over the motion port (see the module)."""

    def __init__(self, motion: Session | None, state: Session | None, *, robot: RobotModel,
                 byteorder: sm.ByteOrder, real: sm.RealSize, timeout: float,
                 history: int) -> None:  # fmt: skip
        stats = (state or motion).stats  # type: ignore[union-attr]
        super().__init__(state, stats, robot=robot, byteorder=byteorder, real=real,
                         timeout=timeout, history=history)  # fmt: skip
        self._motion = motion
        self._stop_frame = stop_frame(robot, byteorder, real)
        #: (host, port) of the motion server, to reconnect and STOP after a lost link
        self.motion_address: tuple[str, int] | None = None

    def _point_frame(self, seq: int, p: Point) -> bytes:
        return point_frame(seq, p, self.byteorder, self.real)

    def _on_motion_frame(self, frame: bytes, t: float) -> None:
        sm.decode(frame, byteorder=self.byteorder, real=self.real)  # unsolicited: checked only

    def send_point(
        self,
        sequence: int,
        joints: npt.ArrayLike,
        *,
        velocity: float = 0.0,
        duration: float = 0.0,
        timeout: float | None = None,
    ) -> float:
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
        return (
            m.msg_type == SimpleMessageType.JOINT_TRAJ_PT and m.comm_type == CommType.SERVICE_REPLY
        )

    def _send_point(self, seq: int, p: Point, timeout: float) -> None:
        s = need(self._motion, "motion")
        order, real, is_reply = self.byteorder, self.real, self._is_reply
        before = s.stats.decode_errors
        try:
            reply = s.request(self._point_frame(seq, p), is_reply, timeout)
        except TimeoutError:
            if s.stats.decode_errors != before:
                raise TransportError(
                    f"{s.transport.url}: the motion port answers, but not in "
                    "Simple Message (another protocol?)"
                ) from None
            raise TimeoutError(
                f"{s.transport.url}: no reply to point {seq} within {timeout:g} s"
            ) from None
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
                "and silently drops the rest (use split=True / --split)"
            )
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
            need(self._state, "state")
        wait = self.timeout if timeout is None else timeout
        total, done = sum(len(c) + (len(c) == 1) for c in chunks), 0
        for k, chunk in enumerate(chunks):
            if k:
                self.wait_until_idle(sum(p.duration for p in chunks[k - 1]) * 4 + 30)
            if len(chunk) == 1:
                chunk = chunk * 2  # industrial_robot_client duplicates single points
            for i, p in enumerate(chunk):
                last = i == len(chunk) - 1
                seq = (
                    SpecialSeq.START_TRAJECTORY_DOWNLOAD
                    if i == 0
                    else (SpecialSeq.END_TRAJECTORY if last else i)
                )
                if last:
                    self._activated(chunk)
                self._send_point(seq, p, wait)
                done += 1
                if progress is not None:
                    progress(done, total)
        return done

    def move_to(
        self, joints: npt.ArrayLike, duration: float | None = None, timeout: float | None = None
    ) -> int:
        """Download a move from where the arm is (needs the state port) to ``joints`` (rad),
        taking ``duration`` s (default: a quarter of the speed limits, at least 0.5 s)."""
        need(self._state, "state")
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
        self._streamed_all()
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
        self.send_point(SpecialSeq.STOP_TRAJECTORY, (0.0,) * self.robot.n_joints, timeout=timeout)
        self._activated_at, self._expected_end, self._target = None, 0.0, None

    def _q_now(self) -> tuple[float, ...] | None:
        sample = self.joints
        return sample.joints if sample is not None else None
