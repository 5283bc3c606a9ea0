"""An arm on Zenoh: joints, TCP pose and status out to any number of watchers, trajectory
uploads in from one controller at a time (:class:`~robocli.bridge.control.ControlGate`).

Keys (``<robot>`` is the bridge's name; see :mod:`robocli.zenoh.robot_keys`):

* ``robocli/<robot>/state``, one put per joint sample: ``t`` (epoch s, received),
  ``joints`` (rad), ``robot_time`` (s on the controller's clock, or null), ``tcp``:
  ``position`` (m, base frame) and ``rotation`` (3x3, rows) of the flange;
* ``robocli/<robot>/status``, one put per STATUS message: ``t``, ``drives_powered``,
  ``e_stopped``, ``in_error``, ``in_motion``, ``motion_possible`` (true, false or null:
  unknown), ``mode``, ``error_code``;
* ``robocli/<robot>/@control/<holder>/trajectory``, queried by the holder with ``{"time":
  [s...], "joints": [[rad...]...], "first_duration": s (optional), "split": bool
  (optional)}`` (who asks is the key's ``<holder>`` chunk): the trajectory is checked
  against the robot model and downloaded (the ABB way); the reply is ``{"points": N}``,
  or an error reply ``{"error": ...}``.

The silence rule does not apply to an arm (a trajectory runs without further commands): a
running trajectory is stopped (STOP, -4) when its controller's liveliness goes, when it
releases the arm, and when the bridge ends.
"""

from __future__ import annotations

import functools
import logging
import queue
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from robocli.bridge.base import Bridge
from robocli.bridge.control import DEFAULT_TOKEN_WAIT_S, ControlGate, answer
from robocli.devices.arm import Arm, JointSample
from robocli.errors import ProtocolError, RobocliError
from robocli.kinematics import fk
from robocli.zenoh.keys import alive_key, info_key, topic_key
from robocli.zenoh.robot_keys import (
    JSON_ENCODING,
    decode,
    holder_key,
    holder_of,
    put,
    reply,
)

if TYPE_CHECKING:
    import zenoh

log = logging.getLogger("robocli.bridge")


class ArmBridge(Bridge):
    """Put ``arm`` (state port needed; motion port for uploads) on ``session`` as ``name``
    until :meth:`close`. The bridge owns neither: close them after it."""

    device = "arm"

    def __init__(self, arm: Arm, session: zenoh.Session, name: str, *,
                 token_wait: float = DEFAULT_TOKEN_WAIT_S) -> None:  # fmt: skip
        super().__init__(name)
        self.arm = arm
        self._uploads: queue.Queue[zenoh.Query | Callable[[], None] | None] = queue.Queue(4)
        z = session
        self.gate = ControlGate(z, self.name, stop=self._stop, silence=None,
                                token_wait=token_wait)  # fmt: skip
        self._state = z.declare_publisher(topic_key(self.name, "state"), encoding=JSON_ENCODING)
        self._status = z.declare_publisher(topic_key(self.name, "status"),
                                           encoding=JSON_ENCODING)  # fmt: skip
        self._trajectory = z.declare_queryable(holder_key(self.name, None, "trajectory"),
                                               self._on_trajectory)  # fmt: skip
        self._info = z.declare_queryable(info_key(self.name), self._on_info)
        self._threads = [
            threading.Thread(target=target, daemon=True, name=f"bridge-arm-{what}-{self.name}")
            for target, what in ((self._publish, "state"), (self._upload, "upload"))
        ]
        for thread in self._threads:
            thread.start()
        self._alive = z.liveliness().declare_token(alive_key(self.name, "arm"))
        self._inbound = (self._trajectory, self._alive)
        self._outbound = (self._info, self._state, self._status)

    def info(self) -> dict[str, Any]:
        """What ``robocli/<robot>/@info`` answers."""
        model = self.arm.robot
        return {
            "name": self.name, "kind": "arm", "model": model.name,
            "joints": model.n_joints, "holder": self.gate.holder,
            "keys": self._keys(("state", "status"), "trajectory"),
        }  # fmt: skip

    # ------------------------------------------------------------------ state out

    def _publish(self) -> None:
        last_status = None

        def put_one(sample: JointSample) -> None:
            nonlocal last_status
            pose = fk(self.arm.robot, sample.joints)[0]
            put(self._state, {
                "t": sample.t + self._offset, "joints": list(sample.joints),
                "robot_time": sample.robot_time,
                "tcp": {"position": pose[:3, 3].tolist(), "rotation": pose[:3, :3].tolist()},
            })  # fmt: skip
            status = self.arm.status
            if status is not None and status is not last_status:
                last_status = status
                put(self._status, {"t": status.t + self._offset, **status.as_dict()})

        arm = self.arm
        self._put_each(lambda timeout: arm.wait_for_state(timeout=timeout), lambda: arm.alive,
                       put_one)  # fmt: skip

    def _check_link(self) -> str:
        self.arm.check()
        return f"{self.name}: the arm's state stopped"

    # ------------------------------------------------------------------ commands in

    def _on_trajectory(self, query: zenoh.Query) -> None:
        """Hand the upload to the upload thread (a download waits for each point's ack)."""
        try:
            self._uploads.put_nowait(query)
        except queue.Full:
            reply(query, {"error": f"{self.name}: busy with other uploads"}, error=True)

    def _upload(self) -> None:
        while True:
            query = self._uploads.get()
            if query is None:
                return
            if callable(query):
                try:
                    query()
                except Exception:
                    log.error("%s: upload failed", self.name, exc_info=True)
                continue
            try:
                answer(query, functools.partial(self._download, query), "upload", self.name)
            finally:
                query.drop()  # type: ignore[no-untyped-call]

    def _download(self, query: zenoh.Query) -> dict[str, Any]:
        what = f"{self.name} trajectory"
        holder = holder_of(query.key_expr, self.name, "trajectory")
        raw = query.payload
        data = decode(raw.to_bytes() if raw is not None else b"", what)
        try:
            times = np.asarray(data.get("time"), dtype=float)
            joints = np.asarray(data.get("joints"), dtype=float)
        except (TypeError, ValueError) as exc:
            raise ProtocolError(f"{what}: time and joints must be numbers ({exc})") from None
        if times.ndim != 1 or joints.ndim != 2 or len(times) != len(joints):
            raise ProtocolError(f"{what}: time (N) and joints (N x joints) must match")
        first = data.get("first_duration")
        n = self.upload(holder, times, joints, split=bool(data.get("split", False)),
                        first_duration=None if first is None else float(first))  # fmt: skip
        return {"points": n}

    def upload(self, holder: str, times: np.ndarray, joints: np.ndarray, *, split: bool = False,
               first_duration: float | None = None) -> int:  # fmt: skip
        """Download ``holder``'s trajectory (on the upload thread: it waits for each point's
        ack) under the gate's rules; :class:`RobocliError` unless ``holder`` holds the arm."""
        what = f"{self.name} trajectory"
        with self.gate.command(holder, moving=False) as ok:
            if not ok:
                raise RobocliError(f"{what}: {holder} does not hold {self.name}"
                                   + (f" ({self.gate.holder} does)" if self.gate.holder
                                      else ""))  # fmt: skip
            return self.arm.download((times, joints), split=split, first_duration=first_duration)

    def queue_work(self, work: Callable[[], None]) -> bool:
        """Run ``work`` on the upload thread (a ROS 2 trajectory); False when busy."""
        try:
            self._uploads.put_nowait(work)
        except queue.Full:
            return False
        return True

    def _stop(self, reason: str) -> None:
        if self.arm.running():
            self.arm.stop()

    # ------------------------------------------------------------------ closing

    def _stop_taking(self) -> None:
        try:
            self._uploads.put(None, timeout=1.0)
        except queue.Full:
            log.warning("%s: uploads still queued at close", self.name)


__all__ = ["ArmBridge"]
