"""A Pioneer through a bridge on Zenoh, as a program or a notebook uses it.

>>> with RemotePioneer.connect("r1", "tcp/192.168.1.10:7447") as robot:  # doctest: +SKIP
...     x, y, th = robot.state.pose         # what the bridge last put (m, m, rad)
...     robot.set_velocity(0.2, 0.0)        # takes the robot; refused while another holds it
...     robot.stop()

Watching needs nothing but the state key; the first command takes the robot (the
holder's ``@control/<holder>/request`` queryable, then its liveliness token). The holder
is the user name of a configuration that authenticates one (a lab's router checks that the
keys under ``@control/<user>/`` are that user's), else ``user-host-pid``. The set-point is
re-sent every ``resend`` seconds until changed, as the Pioneer client's keep-alive does,
so the bridge's 0.5 s silence rule stops the robot only when this program stops or stalls.
:meth:`close` (and leaving the ``with`` block) stops the robot and gives it back.

After a stop it did not ask for (the silence rule, a fault), nothing that moves is sent
again until the program gives a fresh command, which goes out after a stop. Each command
carries the bridge's stop epoch known when the program gave it (see
:mod:`robocli.bridge.control`): a re-send already under way when the stop came, from a
program that stalled, is older than the stop and the bridge ignores it.
"""

from __future__ import annotations

import getpass
import logging
import math
import os
import re
import socket
import threading
import time
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

from robocli.devices.base import ListenerHandle, ZenohPeer, deprecated, pick_kind, zenoh_where
from robocli.devices.listeners import FrameListener, Listeners
from robocli.devices.pioneer.commands import _finite
from robocli.devices.pioneer.state import PioneerState
from robocli.devices.stats import LinkStats
from robocli.errors import (
    ConnectionLost,
    DeviceError,
    InvalidArgument,
    ProtocolError,
    TimeoutError,
)
from robocli.serving.periodic import PeriodicLoop
from robocli.zenoh.keys import alive_key, check_name, info_key, topic_key
from robocli.zenoh.robot_keys import JSON_ENCODING, control_key, decode, encode, holder_key
from robocli.zenoh.session import (
    ZenohTarget,
    close_session,
    config_user,
    import_zenoh,
    open_session,
)

if TYPE_CHECKING:
    import zenoh

log = logging.getLogger("robocli.bridge")

_ZENOH = import_zenoh()
INFO_RETRY_S = 0.1  #: between two info queries that found no bridge yet
_DELETE = _ZENOH.SampleKind.DELETE
#: Seconds between re-sends of a set-point (well inside the bridge's 0.5 s silence rule).
DEFAULT_RESEND_S = 0.15


def default_holder() -> str:
    """``user-host-pid``: a holder name that tells a class who drives."""
    try:
        user = getpass.getuser()
    except Exception:
        user = "user"
    raw = f"{user}-{socket.gethostname().split('.')[0]}-{os.getpid()}"
    return re.sub(r"[^A-Za-z0-9_.\-]", "-", raw)[:63].lstrip(".-") or f"robocli-{os.getpid()}"


class RemotePioneer(ZenohPeer):
    """A Pioneer behind a bridge named ``robot`` (see the module). Make one with
    :meth:`connect`, or hand it an open ``session`` (not closed by :meth:`close`)."""

    def __init__(self, session: zenoh.Session, robot: str, *, holder: str | None = None,
                 timeout: float = 5.0, resend: float = DEFAULT_RESEND_S,
                 own_session: bool = False,
                 listeners: Iterable[FrameListener] = ()) -> None:  # fmt: skip
        self.robot = check_name(robot.removeprefix("zenoh/"), "robot name")
        #: samples received (by key: state, laser, event) and set-points sent
        self.stats = LinkStats()
        self._listeners: dict[str, Listeners[Any]] = {
            kind: Listeners(self.stats, f"zenoh/{self.robot} {kind}")
            for kind in ("frames", "states")
        }
        for listener in listeners:
            self._listeners["frames"].add(listener)
        self.holder = check_name(holder or default_holder(), "holder")
        self.timeout = timeout
        self.resend = resend
        self._session = session
        self._own = own_session
        self._cond = threading.Condition()
        self._state: PioneerState | None = None
        self._laser: dict[str, Any] | None = None
        self._states = 0
        #: epoch - monotonic seconds: a state's ``t`` plus this is Unix time
        self.offset = time.time() - time.monotonic()
        #: (v, w, epoch): the program's set-point and the bridge's stop epoch it was given in
        self._setpoint: tuple[float, float, int | None] | None = None
        self._epoch: int | None = None  # the bridge's latest stop epoch known here
        self._interrupted = False  # a stop we did not ask for: a stop before the next motion
        self._token: Any = None  # our liveliness token while we hold the robot
        self.fault: str | None = None  #: the bridge's last fault or stop reason for us
        self._closed = False
        self._gone: str | None = None  # why the bridge is gone (its @alive token went)
        try:
            self.info = self._query_info()
            self._subs = [
                session.declare_subscriber(topic_key(self.robot, "state"), self._on_state),
                session.declare_subscriber(topic_key(self.robot, "laser"), self._on_laser),
                session.declare_subscriber(control_key(self.robot, "event"), self._on_event),
                session.liveliness().declare_subscriber(
                    alive_key(self.robot, "pioneer"), self._on_alive, history=True
                ),
            ]
        except BaseException:
            if own_session:
                close_session(session)
            raise
        self._resender = PeriodicLoop(f"remote-pioneer-{self.robot}", self._resend,
                                      period=self.resend)  # fmt: skip
        self._resender.start()

    @classmethod
    def connect(cls, robot: str, zenoh: str | ZenohTarget | None = None, *,
                holder: str | None = None, timeout: float = 5.0,
                resend: float = DEFAULT_RESEND_S,
                listeners: Iterable[FrameListener] = ()) -> RemotePioneer:  # fmt: skip
        """Connect to ``zenoh`` (an endpoint such as ``tcp/127.0.0.1:7447``, or a JSON5
        config file; default tcp/127.0.0.1:7447) as a client and find the bridge ``robot``
        (``NAME``, ``zenoh/NAME``, or ``zenoh/NAME?zenoh=ENDPOINT`` with the endpoint in the
        URL): :class:`TimeoutError` when no bridge of that name answers within ``timeout`` s.
        ``holder`` (default: the configuration's user, else :func:`default_holder`): the
        name this program drives as; under a lab's ACL, only its own user name is let
        through. ``listeners``: ``"frames"`` listeners (see :meth:`add_listener`), from the
        first sample on. ``Pioneer.connect("zenoh/NAME...")`` comes here too."""
        robot, zenoh = zenoh_where(robot, zenoh, "RemotePioneer")
        holder = holder or config_user(zenoh)
        session = open_session(zenoh, "client")
        return cls(session, robot, holder=holder, timeout=timeout, resend=resend,
                   own_session=True, listeners=listeners)  # fmt: skip

    # ------------------------------------------------------------------ watching

    @property
    def state(self) -> PioneerState:
        """The latest state the bridge put (``t``: monotonic time here, when it came);
        waits up to ``timeout`` s for the first."""
        with self._cond:
            if self._state is not None:
                return self._state
        return self.wait_for_state()

    @property
    def pose(self) -> tuple[float, float, float]:
        return self.state.pose

    @property
    def battery(self) -> float:
        """Battery voltage (V) of the latest state."""
        return self.state.battery

    @property
    def laser(self) -> dict[str, Any] | None:
        """The latest laser scan as the bridge put it (JSON of ``robocli/<robot>/laser``)."""
        with self._cond:
            return self._laser

    @property
    def url(self) -> str:
        """``zenoh/ROBOT``."""
        return f"zenoh/{self.robot}"

    @property
    def connected(self) -> bool:
        """Deprecated: :attr:`alive`."""
        deprecated("RemotePioneer.connected", "RemotePioneer.alive")
        return self.alive

    def add_listener(self, listener: Any, *, kind: str = "frames") -> ListenerHandle:
        """Call ``listener`` with what ``kind`` names and return a handle whose ``remove()``
        takes it off: ``"frames"``, ``(direction "tx"/"rx", payload, t)`` for every state,
        laser and event sample received and every set-point sent (the JSON payloads);
        ``"states"``, ``listener(state)`` with each :class:`PioneerState`. Called in Zenoh's
        threads: keep it short; one that raises is counted and logged, never stops this."""
        return self._add_listener(listener, kind)

    def _listeners_of(self, kind: str) -> Listeners[Any]:
        return self._listeners[pick_kind(kind, tuple(self._listeners), "RemotePioneer")]

    def _received(self, what: str, sample: zenoh.Sample) -> bytes:
        payload: bytes = sample.payload.to_bytes()
        self.stats.count_received(what)
        self._listeners["frames"].notify("rx", payload, time.monotonic())
        return payload

    def wait_for_state(self, timeout: float | None = None) -> PioneerState:
        """Block until the next state arrives and return it; :class:`ConnectionLost` once
        the bridge left, :class:`TimeoutError` after ``timeout`` s."""
        limit = self.timeout if timeout is None else timeout
        deadline = time.monotonic() + limit
        with self._cond:
            count = self._states
            while self._states == count:
                if self._gone is not None:
                    raise ConnectionLost(f"{self.url}: {self._gone}")
                left = deadline - time.monotonic()
                if left <= 0 or self._closed:
                    raise TimeoutError(f"{self.url}: no state within {limit:g} s")
                self._cond.wait(left)
            assert self._state is not None
            return self._state

    # ------------------------------------------------------------------ driving

    @property
    def held(self) -> bool:
        """True while this program holds the robot."""
        return self._token is not None

    def acquire(self) -> None:
        """Take the robot; :class:`DeviceError` (exit 4) naming the holder when another
        controller holds it, :class:`TimeoutError` when the bridge does not answer."""
        if self._token is not None:
            return
        try:
            reply = self._ask({"op": "acquire"})
        except TimeoutError as exc:
            raise TimeoutError(f"{exc}; under a lab router's ACL only the user {self.holder} "
                               f"may ask as {self.holder}") from None  # fmt: skip
        if not reply.get("granted"):
            raise DeviceError(f"{self.url}: refused: {reply.get('reason') or 'held'} "
                              f"(holder: {reply.get('holder')})")  # fmt: skip
        self._new_epoch(reply.get("epoch"), grant=True)
        self._token = self._session.liveliness().declare_token(
            holder_key(self.robot, self.holder, "alive")
        )
        self.fault = None

    def enable_motors(self) -> None:
        """Take the robot (:meth:`acquire`): the bridge powers its motors when it grants it,
        so a script written for :class:`~robocli.devices.pioneer.Pioneer` runs here as is."""
        self.acquire()

    def set_velocity(self, v: float, w: float = 0.0) -> None:
        """Drive at ``v`` m/s and ``w`` rad/s (CCW +), re-sent until changed; takes the robot
        first (see :meth:`acquire`)."""
        v, w = _finite("v", v), _finite("w", w)
        self.acquire()
        with self._cond:
            epoch, stop_first = self._epoch, self._interrupted and (v, w) != (0.0, 0.0)
            self._interrupted = False
            self._setpoint = (v, w, epoch)
            self._cond.notify_all()
        if stop_first:  # a fresh command after a stop we did not ask for: the stop first
            self._send((0.0, 0.0, epoch))
        self._send((v, w, epoch))

    def stop(self) -> None:
        """Stop the robot (when this program holds it)."""
        if self._token is not None:
            with self._cond:
                self._setpoint = point = (0.0, 0.0, self._epoch)
                self._interrupted = False
            self._send(point)

    def release(self) -> None:
        """Stop the robot and give it back (the bridge stops it as the token goes, too)."""
        token, self._token = self._token, None
        if token is None:
            return
        with self._cond:
            self._setpoint = None
            epoch = self._epoch
        try:
            self._send((0.0, 0.0, epoch))
            if self._gone is None:  # (a bridge that left answers nothing: no wait for it)
                self._ask({"op": "release"})
        finally:
            token.undeclare()

    def close(self, *, stop: bool = True) -> None:
        """Stop and release the robot, stop watching; close the session when it is ours.
        Idempotent. The robot is always stopped (``stop=False`` is refused), as a Pioneer's."""
        if not stop:
            raise InvalidArgument("a Pioneer is always stopped on close (stop=False refused)")
        if self._closed:
            return
        try:
            self.release()
        except Exception:
            log.debug("%s: release failed", self.url, exc_info=True)
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        self._resender.close()
        for sub in self._subs:
            sub.undeclare()  # type: ignore[no-untyped-call]
        if self._own:
            close_session(self._session)

    def __repr__(self) -> str:
        return f"<RemotePioneer {self.robot} as {self.holder}>"

    # ------------------------------------------------------------------ internals

    def _send(self, point: tuple[float, float, int | None]) -> None:
        """Put a set-point (v, w, epoch), ahead of bulk data (camera frames) on a shared
        link: interactive priority, sent at once rather than batched."""
        v, w, epoch = point
        body: dict[str, Any] = {"v": v, "w": w}
        if epoch is not None:  # (a bridge that gave none does not know epochs)
            body["epoch"] = epoch
        payload = encode(body)
        self.stats.count_sent("velocity")
        self._listeners["frames"].notify("tx", payload, time.monotonic())
        self._session.put(holder_key(self.robot, self.holder, "velocity"), payload,
                          encoding=JSON_ENCODING, priority=_ZENOH.Priority.INTERACTIVE_HIGH,
                          express=True)  # fmt: skip

    def _resend(self) -> None:
        """Re-send the moving set-point held now (the silence rule), every ``resend`` s; a
        put that fails is the periodic loop's to log (once per run of failures)."""
        with self._cond:
            point = self._setpoint
            if self._closed or point is None or point[:2] == (0.0, 0.0) or self._token is None:
                return
        self._send(point)  # out of the lock: a stop event is never held up behind it

    def _new_epoch(self, epoch: object, grant: bool = False) -> None:
        """The bridge's stop epoch from an event (a later one only) or a grant (as it is: a
        bridge that started again counts from 1)."""
        if isinstance(epoch, int) and not isinstance(epoch, bool):
            with self._cond:
                if grant or self._epoch is None or epoch > self._epoch:
                    self._epoch = epoch

    def _ask(self, request: dict[str, Any]) -> dict[str, Any]:
        return self._get(holder_key(self.robot, self.holder, "request"), encode(request),
                         "control reply")  # fmt: skip

    def _query_info(self) -> dict[str, Any]:
        """The bridge's info. A query that no queryable is known for yet ends at once with
        no reply (a bridge just started, its declaration still on its way through the
        router): it is asked again until ``timeout`` (it changes nothing on the bridge)."""
        deadline = time.monotonic() + self.timeout
        while True:
            left = deadline - time.monotonic()
            try:
                return self._get(info_key(self.robot), None, "info reply", max(0.05, left))
            except TimeoutError:
                if left <= INFO_RETRY_S:
                    raise
            time.sleep(INFO_RETRY_S)

    def _get(self, key: str, payload: bytes | None, what: str,
             timeout: float | None = None) -> dict[str, Any]:  # fmt: skip
        wait = self.timeout if timeout is None else timeout
        replies = self._session.get(key, payload=payload, timeout=wait)
        for reply in replies:
            if reply.ok is not None:
                return decode(reply.ok.payload.to_bytes(), f"{self.url} {what}")
            if reply.err is not None:
                err = decode(reply.err.payload.to_bytes(), f"{self.url} {what}")
                raise DeviceError(f"{self.url}: {err.get('error', err)}")
        raise TimeoutError(f"{self.url}: no bridge named {self.robot!r} answered within "
                           f"{self.timeout:g} s")  # fmt: skip

    def _on_state(self, sample: zenoh.Sample) -> None:
        try:
            data = decode(self._received("state", sample), f"{self.url} state")
            state = _state_of(data, time.monotonic())
        except ProtocolError as exc:
            log.warning("%s", exc)
            return
        with self._cond:
            self._state = state
            self._states += 1
            self._cond.notify_all()
        self._listeners["states"].notify(state)

    def _on_laser(self, sample: zenoh.Sample) -> None:
        try:
            data = decode(self._received("laser", sample), f"{self.url} laser")
        except ProtocolError as exc:
            log.warning("%s", exc)
            return
        with self._cond:
            self._laser = data

    def _on_alive(self, sample: zenoh.Sample) -> None:
        if sample.kind == _DELETE:
            with self._cond:
                self._gone = f"the bridge {self.robot} left (its liveliness token went)"
                self._setpoint = None
                self._cond.notify_all()

    def _on_event(self, sample: zenoh.Sample) -> None:
        try:
            data = decode(self._received("event", sample), f"{self.url} event")
        except ProtocolError:
            return
        kind = data.get("event")
        if data.get("holder") != self.holder or not (
            kind in ("fault", "released", "stopped") or (kind == "ignored" and "epoch" in data)
        ):
            return
        self.fault = str(data.get("reason"))
        self._new_epoch(data.get("epoch"))
        with self._cond:
            self._setpoint = None  # never re-send a stale set-point after a stop
            self._interrupted = True
        if data.get("event") == "released" and self._token is not None:
            token, self._token = self._token, None
            token.undeclare()


def _state_of(data: dict[str, Any], t: float) -> PioneerState:
    """A :class:`PioneerState` from the JSON of ``robocli/<robot>/state`` (``t``: here)."""
    try:
        sonar = tuple(math.nan if r is None else float(r) for r in data.get("sonar") or ())
        fields = {k: data[k] for k in PioneerState.__dataclass_fields__
                  if k not in ("t", "sonar", "sonar_time")}  # fmt: skip
        for k in ("x", "y", "th", "v", "w", "left_velocity", "right_velocity", "battery",
                  "analog"):  # fmt: skip
            fields[k] = float(fields[k])
        return PioneerState(t=t, sonar=sonar, sonar_time=(t,) * len(sonar), **fields)
    except (KeyError, TypeError, ValueError) as exc:
        raise ProtocolError(f"state: missing or bad field ({exc})") from None


__all__ = ["DEFAULT_RESEND_S", "RemotePioneer", "default_holder"]
