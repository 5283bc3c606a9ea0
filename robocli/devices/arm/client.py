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

:class:`Arm` holds the connection: opening the ports, closing, listeners, counters. Its other
jobs have their own modules, whose classes it inherits: the state port's samples, statuses
and waits (:mod:`robocli.devices.arm.tracking`), and the motion port's points, trajectories,
STOP and lost-link recovery (:mod:`robocli.devices.arm.motion`); the bytes of the links are
in :mod:`robocli.devices.arm.link`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from typing import Any

from robocli.addresses import ARM_PORTS, parse_device_url
from robocli.closing import Closing
from robocli.devices import simulators
from robocli.devices.arm.link import first_state, no_refusal, open_session, stop_frame
from robocli.devices.arm.motion import Motion
from robocli.devices.arm.tracking import SampleListener, StillMoving
from robocli.devices.base import (
    ListenerHandle,
    close_simulator,
    deprecated_listener,
    pick_kind,
    renamed_argument,
)
from robocli.devices.session import FrameListener, Session
from robocli.errors import InvalidArgument
from robocli.kinematics import load_model
from robocli.kinematics.model import RobotModel
from robocli.protocols import simple_message as sm

__all__ = ["Arm", "SampleListener", "StillMoving"]

_ORDERS = {"little": "<", "big": ">", "<": "<", ">": ">"}


class Arm(Motion, Closing):
    """A connected arm controller. Make one with :meth:`connect`; use it as a context manager.

    ``robot``: the :class:`~robocli.kinematics.model.RobotModel` limits are checked against.
    ``history``: joint samples kept (oldest dropped).
    """

    def __init__(self, motion: Session | None, state: Session | None, *, robot: RobotModel,
                 byteorder: sm.ByteOrder, real: sm.RealSize, timeout: float,
                 history: int = 10_000) -> None:  # fmt: skip
        """Use :meth:`connect`."""
        super().__init__(motion, state, robot=robot, byteorder=byteorder, real=real,
                         timeout=timeout, history=history)  # fmt: skip
        for session, handler in ((motion, self._on_motion_frame), (state, self._on_state_frame)):
            if session is not None:
                session.on_frame = handler

    # ------------------------------------------------------------------ connecting

    @classmethod
    def connect(cls, url: str | None = None, motion_port: int | None = None,
                state_port: int | None = None, *, byte_order: str = "little",
                real_size: int = 4, robot: str | RobotModel = "irb120", motion: bool = True,
                state: bool = True, timeout: float = 5.0, history: int = 10_000,
                listeners: Iterable[FrameListener] | Mapping[str, Iterable[FrameListener]] = (),
                stop_on_failure: bool = True, host: str | None = None) -> Arm:  # fmt: skip
        """Open the motion and/or state port of the controller at ``url``: ``HOST``,
        ``tcp://HOST?motion=11000&state=11002`` (the ports in the URL; else
        ``motion_port``/``state_port``, default 11000 and 11002), or ``sim://[MODEL][?...]``,
        the built-in simulator started in-process and closed with the arm
        (``sim://?profile=generic`` executes streamed points). ``host`` is the deprecated
        old name of ``url``.

        ``byte_order``: ``"little"`` (ABB) or ``"big"`` (Fanuc, FS100); ``real_size`` 4 or 8.
        With ``state``, waits up to ``timeout`` s for the first state message. A motion link
        that fails sends STOP (-4) on its way down unless ``stop_on_failure=False`` (an
        observer such as ``dump arm``, which never sends anything). ``listeners`` see every
        frame from each port's first byte on (a mapping from ``"motion"``, ``"state"`` or
        ``"both"`` to listeners: on those ports only; else on both). Raises
        :class:`TransportError` (unreachable, or a port answering another protocol),
        :class:`DeviceError` (the controller refused: another client holds the port),
        :class:`InvalidArgument` (bad option), an unknown-model error (exit 2).
        """
        order = _ORDERS.get(byte_order)
        if order is None:
            raise InvalidArgument(f"byte_order must be 'little' or 'big', not {byte_order!r}")
        if real_size not in (4, 8):
            raise InvalidArgument(f"real_size must be 4 or 8, not {real_size!r}")
        text = renamed_argument("Arm.connect", "host", "url", host, url, None)
        if text is None:
            raise InvalidArgument("Arm.connect: give the controller's URL")
        where = parse_device_url(text, ports=ARM_PORTS, what="arm URL")
        options: dict[str, Any] = {
            "byte_order": byte_order, "real_size": real_size, "robot": robot,
            "motion": motion, "state": state, "timeout": timeout, "history": history,
            "listeners": listeners, "stop_on_failure": stop_on_failure,
        }  # fmt: skip
        if where.kind == "sim":
            return simulators.connect_to(  # type: ignore[no-any-return]
                "arm", where, lambda sim: cls.connect(
                    "127.0.0.1", sim.port("motion"), sim.port("state"), **options),
                real=real_size, byteorder=order,
            )  # fmt: skip
        if where.kind != "tcp":
            raise InvalidArgument(
                f"arm URL {text!r}: an arm is reached over TCP "
                "(HOST, tcp://HOST?motion=PORT&state=PORT or sim://)"
            )
        host = where.host
        motion_port = _one_port("motion", where.ports, motion_port, sm.PORT_MOTION)
        state_port = _one_port("state", where.ports, state_port, sm.PORT_STATE)
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
            by_port = listeners if isinstance(listeners, Mapping) else {"both": listeners}
            for which, some in by_port.items():
                for listener in some:
                    arm.add_listener(listener, ports=which)
            if arm._state is not None:
                first_state(arm._state, timeout)
            if arm._motion is not None:  # (after the state's first message: no extra wait)
                no_refusal(arm._motion, 0.01 if arm._state is not None else 0.1)
            for s in sessions:
                s.start()
            if arm._motion is not None:
                arm._motion.close_timeout = 2.0
            return arm
        except BaseException:
            for s in sessions:
                s.close()
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
        an ABB. Then the simulator of a ``sim://`` URL. Bounded in time; idempotent."""
        try:
            if self._motion is not None:
                seq = [self._stop_frame] if stop and self.running() else []
                self._motion.close(seq)
            if self._state is not None:
                self._state.close()
            with self._cond:
                self._cond.notify_all()
        finally:
            close_simulator(self)

    #: the in-process simulator of a ``sim://`` URL (None otherwise), closed with the arm
    simulator: simulators.Simulator | None = None

    # ------------------------------------------------------------------ listeners

    def add_listener(self, listener: Callable[..., None], ports: str = "both", *,
                     kind: str = "frames") -> ListenerHandle:  # fmt: skip
        """Call ``listener`` with what ``kind`` names and return a handle whose ``remove()``
        takes it off: ``"frames"``, ``listener(direction, frame, t)`` for every frame sent
        ("tx") or received ("rx") on the ``"motion"``, ``"state"`` or ``"both"`` ports;
        ``"samples"``, ``listener(sample)`` for each :class:`JointSample`. A listener that
        raises is logged once, counted in ``stats.listener_errors``, and never stops the
        client."""
        pick_kind(kind, ("frames", "samples"), "Arm")
        if kind == "samples":
            self._sample_listeners.add(listener)
        else:
            for s in self._sessions(ports):
                s.listeners.add(listener)
        return ListenerHandle(listener, lambda: self.remove_listener(listener, ports, kind=kind))

    def remove_listener(self, listener: Callable[..., None], ports: str = "both", *,
                        kind: str = "frames") -> None:  # fmt: skip
        pick_kind(kind, ("frames", "samples"), "Arm")
        if kind == "samples":
            self._sample_listeners.remove(listener)
            return
        for s in self._sessions(ports):
            s.listeners.remove(listener)

    add_sample_listener = deprecated_listener("Arm", "add_sample_listener", "samples")
    remove_sample_listener = deprecated_listener("Arm", "remove_sample_listener", "samples",
                                                 remove=True)  # fmt: skip

    def _sessions(self, ports: str) -> list[Session]:
        if ports not in ("both", "motion", "state"):
            raise InvalidArgument(f"ports must be 'motion', 'state' or 'both', not {ports!r}")
        picked = [(self._motion, "motion"), (self._state, "state")]
        return [s for s, name in picked if s is not None and ports in ("both", name)]

    @property
    def stats(self) -> ArmStats:
        """Counters of both links (JSON-ready): ``stats["motion"]``, ``stats.as_dict()``."""
        return ArmStats({name: s.stats.as_dict() for s, name in
                ((self._motion, "motion"), (self._state, "state")) if s is not None})  # fmt: skip


class ArmStats(dict[str, Any]):
    """The counters of an arm's links by port name; :meth:`as_dict` as every device's."""

    def as_dict(self) -> dict[str, Any]:
        return dict(self)


def _one_port(name: str, in_url: dict[str, int], given: int | None, default: int) -> int:
    port = in_url.get(name)
    if port is not None and given is not None and given != port:
        raise InvalidArgument(f"the {name} port is {port} in the URL and {given} in "
                              f"{name}_port: give it once")  # fmt: skip
    return port if port is not None else given if given is not None else default
