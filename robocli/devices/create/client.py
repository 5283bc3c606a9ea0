"""An iRobot Create 2 read over its Open Interface: the sensor stream, pose from odometry.

>>> with Create.connect("/dev/ttyUSB0") as robot:      # doctest: +SKIP
...     state = robot.wait_for_state()               # bumpers, battery, pose (m, rad)

Connecting sends start (128: passive mode; nothing moves) and asks the stream (148) of
:data:`STREAMED`: the bumps and wheel drops, distance and angle, the battery and the OI mode.
Every frame (15 ms) becomes a :class:`CreateState`; the pose is the sum of the distance and
angle packets since the connection (odometry, frame ``odom``). This client never commands
motion. :meth:`Create.close` pauses the stream (bounded) and closes the link.

On the shared :class:`~robocli.devices.session.Session`: the reader thread takes the
frames (:class:`~robocli.protocols.create_oi.StreamFramer`: garbage dropped and counted,
bad checksums counted); a frame that does not decode is counted and skipped.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from robocli.closing import Closing
from robocli.devices.listeners import FrameListener, Listeners
from robocli.devices.session import Session
from robocli.errors import TimeoutError
from robocli.protocols import create_oi as oi
from robocli.protocols.create_oi import Op
from robocli.transports import Transport, open_transport

__all__ = ["STREAMED", "Create", "CreateOdometry", "CreateState", "StateListener"]

#: The packets streamed: bumps and wheel drops, distance, angle, charging state, voltage,
#: current, charge, capacity, OI mode.
STREAMED = (7, 19, 20, 21, 22, 23, 25, 26, 35)


@dataclass(frozen=True)
class CreateState:
    """One stream frame in SI units. ``t``: monotonic receive time (s). ``x, y, th``:
    odometry since the connection (m, m, rad in [-pi, pi)). Battery: ``voltage`` V,
    ``current`` A (negative: discharging), ``charge`` and ``capacity`` Ah. ``mode``: 0 off,
    1 passive, 2 safe, 3 full. ``frames``: frames received so far."""

    t: float
    x: float
    y: float
    th: float
    bump_left: bool
    bump_right: bool
    wheel_drop_left: bool
    wheel_drop_right: bool
    voltage: float
    current: float
    charge: float
    capacity: float
    charging_state: int
    mode: int
    frames: int


StateListener = Callable[[CreateState], None]


class CreateOdometry:
    """The pose from the distance (mm) and angle (degrees) packets, summed (the recorder
    keeps its own, so that every recorded pose is the frame's it was decoded from)."""

    def __init__(self) -> None:
        self.x = self.y = self.th = 0.0

    def update(self, distance_mm: int, angle_deg: int) -> tuple[float, float, float]:
        dth = math.radians(angle_deg)
        mid = self.th + dth / 2.0
        self.x += distance_mm / 1000.0 * math.cos(mid)
        self.y += distance_mm / 1000.0 * math.sin(mid)
        self.th = math.remainder(self.th + dth, 2 * math.pi)
        return self.x, self.y, self.th


def state_of(fields: dict[str, int], t: float, pose: tuple[float, float, float],
             frames: int) -> CreateState:  # fmt: skip
    """A :class:`CreateState` of one frame's decoded fields."""
    bits = fields.get("bumps_wheel_drops", 0)
    return CreateState(
        t, *pose, bump_left=bool(bits & 2), bump_right=bool(bits & 1),
        wheel_drop_left=bool(bits & 8), wheel_drop_right=bool(bits & 4),
        voltage=fields.get("voltage", 0) / 1000.0, current=fields.get("current", 0) / 1000.0,
        charge=fields.get("battery_charge", 0) / 1000.0,
        capacity=fields.get("battery_capacity", 0) / 1000.0,
        charging_state=fields.get("charging_state", 0), mode=fields.get("oi_mode", 0),
        frames=frames,
    )  # fmt: skip


class Create(Closing):
    """A Create 2's sensors over a byte stream (see the module docstring)."""

    def __init__(self, transport: Transport, *, timeout: float = 2.0) -> None:
        self.url = transport.url
        self.timeout = timeout
        framer: Any = oi.StreamFramer()  # the Framer interface, in Python
        self._session = Session(transport, framer, on_frame=self._on_frame,
                                name=f"create {transport.url}")  # fmt: skip
        self._odo = CreateOdometry()
        self._state: CreateState | None = None
        self._frames = 0
        self._state_listeners: Listeners[StateListener] = Listeners(self._session.stats,
                                                                    self.url)  # fmt: skip

    @classmethod
    def connect(
        cls, url: str, *, timeout: float = 2.0, baudrate: int = 115200,
        listeners: Sequence[FrameListener] = (),
    ) -> Create:  # fmt: skip
        """Open ``url`` (a serial port, a pyserial URL, ``tcp://host:port``), start the OI
        and the stream; returns once the first frame came (else
        :class:`~robocli.errors.TimeoutError` within ``timeout``). ``listeners`` see every
        command and stream frame from the first (``(direction, bytes, t)``)."""
        transport = open_transport(url, baudrate=baudrate, timeout=max(timeout, 1.0))
        robot = cls(transport, timeout=timeout)
        for listener in listeners:
            robot.add_listener(listener)
        try:
            robot._session.start()
            robot._session.send(oi.build_command(Op.START))
            robot._session.send(oi.build_command(Op.STREAM, packets=list(STREAMED)))
            robot.wait_for_state(timeout)
        except BaseException:
            robot.close()
            raise
        return robot

    # ---------------------------------------------------------------- readings

    @property
    def session(self) -> Session:
        """The link (statistics, listeners, errors)."""
        return self._session

    @property
    def state(self) -> CreateState | None:
        """The latest frame's state (None before the first)."""
        return self._state

    def wait_for_state(self, timeout: float | None = None) -> CreateState:
        """The next frame's state (within ``timeout``, default the connect's)."""
        limit = self.timeout if timeout is None else timeout
        session = self._session
        with session.cond:
            seen = self._frames
            came = session.cond.wait_for(lambda: self._frames > seen or not session.alive, limit)
        if not session.alive:
            session.check()
        if not came or self._state is None:
            raise TimeoutError(f"{self.url}: no sensor stream frame in {limit:g} s")
        return self._state

    def add_listener(self, listener: FrameListener) -> None:
        """``listener(direction, bytes, t)`` sees every command sent and frame received."""
        self._session.listeners.add(listener)

    def remove_listener(self, listener: FrameListener) -> None:
        self._session.listeners.remove(listener)

    def on_state(self, listener: StateListener) -> None:
        """``listener(state)`` is called in the reader thread with every frame's state."""
        self._state_listeners.add(listener)

    def remove_state_listener(self, listener: StateListener) -> None:
        self._state_listeners.remove(listener)

    def _on_frame(self, frame: bytes, t: float) -> None:
        fields: dict[str, int] = {}
        for _, values in oi.parse_stream(frame):  # ProtocolError: counted by the session
            fields.update(values)
        pose = self._odo.update(fields.get("distance", 0), fields.get("angle", 0))
        with self._session.cond:
            self._frames += 1
            self._state = state = state_of(fields, t, pose, self._frames)
            self._session.cond.notify_all()
        self._state_listeners.notify(state)

    # ---------------------------------------------------------------- closing

    def close(self) -> None:
        """Pause the stream (bounded) and close the link. Idempotent."""
        self._session.close([oi.build_command(Op.PAUSE_RESUME_STREAM, resume=0)])
