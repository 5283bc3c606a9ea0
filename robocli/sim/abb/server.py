"""Built-in ABB arm simulator: the RAPID ``abb_driver`` servers over Simple Message.

Two TCP servers on the shared serving layer, one client each (a second one is refused), as
on the IRC5 controller (docs/protocols/simple-message.md section 4):

* **motion** (11000): JOINT_TRAJ_PT only; each SERVICE_REQUEST acknowledged header-only
  SUCCESS, even a point dropped because the 100-point buffer is full; ``-1`` starts a
  download, ``-3`` ends and activates it, ``-4`` stops. Any other message type stops the RAPID
  task: the link is closed and the server accepts the next client. The points' durations give
  the timing; a first point within 0.1 deg of the arm is skipped; the velocity field is
  ignored. A dropped link loses the points not yet activated, but **an activated trajectory
  runs to its end**: only STOP or a new activation pre-empts it.
* **state** (11002): JOINT_POSITION (sequence 0) then STATUS every ``state_ms`` (100 ms in
  the stock RAPID code; the paper saw 20 ms). ``feedback=True`` adds a JOINT_FEEDBACK
  carrying the controller time (not sent by an ABB; Motoman sends one): a client then stamps
  samples with robot time, exact to the float.

``profile="generic"`` is an industrial_robot_client-style streaming server instead: points
``0..N`` execute as they arrive (``0`` starts anew), each SERVICE_REQUEST is answered with an
echo of the point, FAILURE for a bad point (velocity outside 0..1, negative duration, NaN,
joint beyond its limit, out of order), PING answered, any other request refused with a
header-only FAILURE (like ``MessageManager``).

Time: ``time_scale`` simulated seconds run per wall second (tests run faster than real time).
With :class:`~robocli.sim.abb.session.ControllerModel` all zero (the default) execution is
exact and states are sampled at their nominal instants ``k * state_ms``.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from robocli.closing import Closing
from robocli.errors import TimeoutError, TransportError
from robocli.kinematics import load_model
from robocli.kinematics.model import RobotModel
from robocli.protocols import simple_message as sm
from robocli.serving.periodic import PeriodicLoop
from robocli.serving.server import Link, Server
from robocli.sim.abb.session import (
    PROFILES,
    ArmController,
    ControllerModel,
    MotionSession,
    StateSession,
)

__all__ = ["PROFILES", "AbbSim", "ArmSimState", "ControllerModel"]

log = logging.getLogger("robocli.sim.abb.server")

SEND_TIMEOUT_S = 2.0
MAX_CATCH_UP_S = 5.0  #: exact and jitter modes send states this late (wall s); older are skipped
MAX_BURST = 5000  #: and at most this many at once
BYTE_TIMEOUT_S = 0.5


@dataclass(frozen=True)
class ArmSimState:
    """A copy of the simulator's truth: joints (rad), simulated seconds, counters."""

    joints: tuple[float, ...]
    sim_time: float
    in_motion: bool
    trajectories: int
    points_received: int
    dropped_points: int
    rejected_points: int
    frames_refused: int
    stops: int
    buffered: int
    motion_clients: int
    state_clients: int
    motion_accepted: int
    state_accepted: int
    states_sent: int


class AbbSim(Closing):
    """A simulated arm controller. Use as a context manager; :meth:`serve_tcp` starts it.

    ``robot``: model name or file. ``state_ms``: state period in simulated ms.
    ``byteorder``/``real``: wire variant. ``q0``: start joints (rad; default the model's
    work pose, where ``robocli traj`` starts). ``model``: the real-controller model.
    """

    def __init__(self, robot: str | RobotModel = "irb120", *, profile: str = "abb",
                 state_ms: float = 100.0, byteorder: sm.ByteOrder = "<", real: sm.RealSize = 4,
                 time_scale: float = 1.0, q0: npt.ArrayLike | None = None,
                 model: ControllerModel | None = None, feedback: bool = False,
                 seed: int = 0) -> None:  # fmt: skip
        if not (0.5 <= state_ms <= 10_000):
            raise ValueError("state_ms must be within 0.5..10000")
        if not time_scale > 0:
            raise ValueError("time_scale must be > 0")
        self.robot = robot if isinstance(robot, RobotModel) else load_model(robot)
        self.state_ms, self.time_scale, self.feedback = state_ms, time_scale, feedback
        self.ctl_model = model or ControllerModel()
        self._t0 = time.monotonic()
        self.controller = ArmController(
            self.robot, profile=profile, byteorder=byteorder, real=real, q0=q0,
            ctl_model=self.ctl_model, clock=self.sim_time, seed=seed,
        )  # fmt: skip
        self._rng = np.random.default_rng(seed + 1)
        self._motion: Server | None = None
        self._state: Server | None = None
        self._publisher: PeriodicLoop | None = None
        self.states_sent = 0
        self._closed = False

    # ---------------------------------------------------------------- public API

    def sim_time(self) -> float:
        """Simulated seconds since the simulator was made."""
        return (time.monotonic() - self._t0) * self.time_scale

    @property
    def motion_url(self) -> str | None:
        return self._motion.url if self._motion else None

    @property
    def state_url(self) -> str | None:
        return self._state.url if self._state else None

    def serve_tcp(
        self,
        host: str = "127.0.0.1",
        motion_port: int = sm.PORT_MOTION,
        state_port: int = sm.PORT_STATE,
    ) -> tuple[str, str]:
        """Listen on both ports (0: ephemeral); returns their ``tcp://`` URLs."""
        if self._closed or self._motion is not None:
            raise TransportError("the simulator is closed or already serving")
        proto = "sm-le" if self.controller.byteorder == "<" else "sm-be"
        ctl = self.controller

        def server(name: str, factory: Any) -> Server:
            return Server(factory, protocol=proto, max_clients=1, max_frame=sm.MAX_FRAME_SIZE,
                          byte_timeout=BYTE_TIMEOUT_S, send_timeout=SEND_TIMEOUT_S,
                          name=name)  # fmt: skip

        self._motion = server("abb-motion", lambda link: MotionSession(ctl, link))
        self._state = server("abb-state", lambda link: StateSession(ctl, link))
        try:
            urls = (self._motion.serve_tcp(host, motion_port),
                    self._state.serve_tcp(host, state_port))  # fmt: skip
        except BaseException:
            self.close()
            raise
        # a state that fails to build is logged and counted; the stream goes on
        self._publisher = PeriodicLoop("abb-state-ticker", self._publish_step())
        self._publisher.start()
        return urls

    def close(self) -> None:
        """Stop every thread and close every socket (bounded). Idempotent."""
        if self._closed:
            return
        self._closed = True
        if self._publisher is not None:
            self._publisher.close(2.0)
        for server in (self._motion, self._state):
            if server is not None:
                server.close()

    def snapshot(self) -> ArmSimState:
        """A consistent copy of the truth (thread-safe)."""
        c = self.controller
        t = self.sim_time()
        with c.lock:
            q, moving = c.executor.sample(t), c.executor.moving(t)
            counters = (c.executor.trajectories, c.points_received, c.dropped_points,
                        c.rejected_points, c.frames_refused, c.stops, len(c.buffer))  # fmt: skip
        # accepted before links: a link is counted and listed under one server lock, so
        # "n accepted, 0 open" then means the n-th has really gone (not: not yet listed)
        accepted = [srv.accepted if srv else 0 for srv in (self._motion, self._state)]
        open_now = [len(srv.links()) if srv else 0 for srv in (self._motion, self._state)]
        return ArmSimState(
            tuple(float(v) for v in q), t, moving, *counters,
            motion_clients=open_now[0], state_clients=open_now[1],
            motion_accepted=accepted[0], state_accepted=accepted[1],
            states_sent=self.states_sent,
        )  # fmt: skip

    def wait_until(self, predicate: Any, timeout: float) -> ArmSimState:
        """Poll snapshots until ``predicate(state)`` holds, or raise TimeoutError."""
        deadline = time.monotonic() + timeout
        while True:
            state = self.snapshot()
            if predicate(state):
                return state
            if time.monotonic() >= deadline:
                raise TimeoutError(f"simulator condition not met within {timeout:g} s")
            time.sleep(0.005)

    # ---------------------------------------------------------------- state publishing

    def _publish_step(self) -> Callable[[], float]:
        """The step of the state stream's loop: state messages on absolute deadlines
        ``k * period``. Exact mode: each sample is taken at its nominal instant, missed ones
        are sent late rather than skipped (up to :data:`MAX_CATCH_UP_S` late), and with
        ``feedback`` the instants a motion starts and ends are reported too. With the
        model's period jitter each period is drawn afresh
        (:meth:`ControllerModel.state_period_ms`) from the previous deadline, and each sample
        is taken at its deadline; missed ones are sent late, as in exact mode, so that the
        stamps follow the model however loaded the host is. Otherwise a sample is taken when
        sent, and a late publisher skips the missed ones. The step returns the seconds until
        its next deadline."""
        period = self.state_ms / 1000.0  # simulated s
        wall = period / self.time_scale
        k = int(self.sim_time() / period) + 1
        exact = self.ctl_model.exact
        renewal = self.ctl_model.period_jitter_ms > 0.0
        due, last_t = self._t0 + k * wall, k * period - period
        burst = max(1, min(MAX_BURST, int(MAX_CATCH_UP_S / wall)))

        def step() -> float:
            nonlocal k, due, last_t
            now = time.monotonic()
            if now < due:
                return due - now
            now_k = int((now - self._t0) / wall)
            if exact:
                times = [j * period for j in range(max(k, now_k - burst + 1), now_k + 1)]
                times = times or [k * period]
                if self.feedback:
                    times = self._with_events(last_t, times)
                k = max(k, now_k) + 1
                due = self._t0 + k * wall
            elif renewal:  # every deadline passed, sampled at its instant, the next from it
                due = max(due, now - MAX_CATCH_UP_S)
                times = []
                while due <= now and len(times) < MAX_BURST:
                    times.append((due - self._t0) * self.time_scale)
                    drawn = self.ctl_model.state_period_ms(self._rng, self.state_ms)
                    due += drawn / 1000.0 / self.time_scale
                if not times:
                    return due - time.monotonic()
            else:
                times = [self.sim_time()]
                k = max(k, now_k) + 1 if now_k > k else k + 1
                due = self._t0 + k * wall
            last_t = times[-1]
            links: list[Link] = self._state.links() if self._state else []
            if not links:
                return due - time.monotonic()
            data = b"".join(self.controller.state_messages(t, self.feedback) for t in times)
            for link in links:
                if link.send(data):
                    self.states_sent += len(times)
            return due - time.monotonic()

        return step

    def _with_events(self, after: float, times: list[float]) -> list[float]:
        """``times`` plus the motion's start and end instants within ``(after, times[-1]]``."""
        with self.controller.lock:
            events = self.controller.executor.events()
        wire = np.float32 if self.controller.real == 4 else np.float64
        seen = {wire(t) for t in times}
        last = times[-1]  # not the events appended below: a late batch may span several
        for e in sorted(set(events)):
            if after < e < last and wire(e) not in seen:
                seen.add(wire(e))
                times.append(e)
        return sorted(times)
