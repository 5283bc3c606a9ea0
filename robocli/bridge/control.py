"""One controller at a time for a robot on Zenoh, and the rules that stop the robot.

A controller named NAME asks the queryable ``robocli/<robot>/@control/NAME/request`` with
the JSON payload ``{"op": "acquire"}``; the reply is ``{"granted": true, "holder": NAME}``,
or ``{"granted": false, "holder": OTHER, "reason": ...}`` while OTHER holds the robot. It
then declares the liveliness token ``robocli/<robot>/@control/NAME/alive`` for as long as
it holds the robot, and puts its commands under ``robocli/<robot>/@control/NAME/``.
``{"op": "release"}`` gives the robot back; the queryable ``robocli/<robot>/@control``
tells who holds it. Commands from anyone else are ignored (counted, and announced once as
an event). NAME is taken from the key, never from a payload: under the lab router's ACL
(:mod:`robocli.zenoh.acl`) only the user NAME can put, query or declare a token there.

The robot is **stopped** (:class:`ControlGate` calls ``stop(reason)``):

* when the holder's commands stop for ``silence`` seconds (0.5 by default) while the robot
  was commanded to move: the holder keeps the robot, its next command moves it again;
* when the holder's liveliness token goes (its process ended or was killed, its link broke,
  its lease expired), or when no token came within ``token_wait`` seconds of the grant: the
  robot is released;
* when the holder releases the robot, and when the gate closes (the bridge ends).

Every grant, refusal, stop and release is put on ``robocli/<robot>/@control/event``. The
stops run in the gate's own thread; a stop that raises is logged and counted
(``stop_errors``), and never ends that thread.

**Set-points older than a stop.** Every stop the gate makes (and every fault a bridge reports
with :meth:`ControlGate.fault`) begins a new *epoch*, a number the bridge counts: the grant
reply and each ``stopped``, ``released`` and ``fault`` event carry it, and a controller puts
the epoch it knew when its program gave the command in each command (``"epoch": N``). A
command that moves and carries an older epoch is ignored (``stale_commands``; the first per
epoch announced with the current epoch): a set-point a stalled controller re-sends after the
stop cannot move the robot, whatever order the stop event and the re-send reach either side,
and no clock is compared. A command without an epoch moves the robot only when its holder
sent a stop since the last stop the gate made (``v`` = ``w`` = 0 is always taken).
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

from robocli.errors import ProtocolError, RobocliError
from robocli.serving.periodic import PeriodicLoop
from robocli.zenoh.keys import check_name
from robocli.zenoh.robot_keys import (
    JSON_ENCODING,
    control_key,
    decode,
    encode,
    holder_key,
    holder_of,
    reply,
    text,
    undeclare,
)
from robocli.zenoh.session import import_zenoh

if TYPE_CHECKING:
    import zenoh

log = logging.getLogger("robocli.bridge")
_PUT = import_zenoh().SampleKind.PUT

#: Seconds without a command from the holder after which a moving robot is stopped.
DEFAULT_SILENCE_S = 0.5
#: Seconds a granted holder has to declare its liveliness token before it loses the robot.
DEFAULT_TOKEN_WAIT_S = 5.0


def answer(query: zenoh.Query, work: Callable[[], dict[str, Any]], what: str, who: str) -> None:
    """Reply to ``query`` with what ``work()`` returns: every query gets one reply. A
    :class:`RobocliError` (a refusal, a bad request) is an error reply with its message;
    anything else is a bug, logged under ``who`` and answered "``what`` failed: ..."."""
    try:
        result = work()
    except RobocliError as exc:
        reply(query, {"error": str(exc)}, error=True)
    except Exception as exc:
        log.error("%s: %s failed", who, what, exc_info=True)
        reply(query, {"error": f"{what} failed: {exc}"}, error=True)
    else:
        reply(query, result)


class ControlGate:
    """Who holds one robot, and when it must stop (see the module docstring).

    ``stop(reason)`` stops the robot (it may raise: logged, counted); ``grant(holder)``
    prepares the robot for a new holder (a Pioneer's motors on); a grant that raises is
    answered as refused. ``silence`` None disables the silence rule (the holder's
    liveliness and the bridge's end still stop the robot)."""

    def __init__(
        self,
        session: zenoh.Session,
        robot: str,
        *,
        stop: Callable[[str], None],
        grant: Callable[[str], None] | None = None,
        silence: float | None = DEFAULT_SILENCE_S,
        token_wait: float = DEFAULT_TOKEN_WAIT_S,
    ) -> None:
        self.robot = check_name(robot, "robot name")
        self.silence = silence
        self.token_wait = token_wait
        self._stop = stop
        self._grant = grant
        self._cond = threading.Condition()
        self._robot_lock = threading.RLock()  # commands and stops reach the robot in turn
        self.holder: str | None = None  #: the controller holding the robot, None when free
        self.counts = {"grants": 0, "refusals": 0, "stops": 0, "stop_errors": 0,
                       "ignored_commands": 0, "commands": 0, "stale_commands": 0}  # fmt: skip
        #: counts the stops the gate made and the faults reported: a moving command from an
        #: earlier epoch is stale (see the module docstring)
        self.epoch = 1
        self._stopped_at = 0  # the epoch of the holder's last stop command (no-epoch rule)
        self._stale_told = 0  # the last epoch whose first stale command was announced
        self._alive: set[str] = set()  # holder names whose tokens are up
        self._token_seen = False
        self._granted_at = 0.0
        self._last_command = 0.0
        self._moving = False  # the last command asked the robot to move
        self._pending: list[tuple[str, bool]] = []  # (reason, release) for the gate thread
        self._warned: set[str] = set()
        self._closed = False
        # the stop rules' thread: a step that raises is logged and counted, and the rules go
        # on (robocli.serving.periodic's policy): their end would leave the robot moving
        self._loop = PeriodicLoop(f"bridge-control-{robot}", self._step)
        self._events = session.declare_publisher(control_key(robot, "event"),
                                                 encoding=JSON_ENCODING)  # fmt: skip
        self._tokens = session.liveliness().declare_subscriber(
            holder_key(robot, None, "alive"), self._on_token, history=True
        )
        self._queryable = session.declare_queryable(control_key(robot), self._on_query)
        self._requests = session.declare_queryable(holder_key(robot, None, "request"),
                                                   self._on_query)  # fmt: skip
        self._loop.start()

    # ------------------------------------------------------------------ commands

    @contextmanager
    def command(self, holder: object, moving: bool, epoch: object = None) -> Iterator[bool]:
        """Around one command of ``holder``: yields True when it holds the robot and the
        command is not older than the last stop (run the command then; ``moving``: it asks
        the robot to move; ``epoch``: the one the command carries, or None), False otherwise
        (ignore it). Stops wait for the command to finish, so a command never lands after a
        stop that released its holder."""
        with self._robot_lock:
            with self._cond:
                ok = not self._closed and holder is not None and holder == self.holder
                stale = ok and moving and self._stale(epoch)
                if stale:
                    ok = False
                    self.counts["stale_commands"] += 1
                    told, current = self._stale_told, self.epoch
                    self._stale_told = current
                elif ok:
                    if not moving:
                        self._stopped_at = self.epoch
                    self._last_command = time.monotonic()
                    self._moving = moving
                    self.counts["commands"] += 1
                    self._loop.wake()
                else:
                    self.counts["ignored_commands"] += 1
                    who = str(holder)[:64]
                    first = who not in self._warned and len(self._warned) < 64
                    self._warned.add(who)
            if stale:
                if told != current:
                    self.event("ignored", holder=holder, epoch=current,
                               reason=f"a set-point older than the stop at epoch {current} "
                               "(send a fresh command)")  # fmt: skip
            elif not ok and first:
                self.event("ignored", holder=who, reason=f"{who} does not hold {self.robot}"
                           + (f" ({self.holder} does)" if self.holder else ""))  # fmt: skip
            yield ok

    def _stale(self, epoch: object) -> bool:
        """A moving command with ``epoch`` is older than the last stop (condition held)."""
        if epoch is None:
            return self._stopped_at != self.epoch
        return epoch != self.epoch

    def fault(self, reason: str) -> None:
        """A fault the bridge found (the robot was stopped without the gate: a stall past
        its watchdog): a new epoch, so set-points from before it are stale; an event."""
        with self._cond:
            self.epoch += 1
            holder, epoch = self.holder, self.epoch
        self.event("fault", holder=holder, reason=reason, epoch=epoch)

    def event(self, kind: str, **fields: Any) -> None:
        """Put ``{"t": epoch s, "event": kind, **fields}`` on the event key (never raises)."""
        try:
            self._events.put(encode({"t": time.time(), "event": kind, **fields}))
        except Exception:
            log.debug("event %s not put", kind, exc_info=True)

    # ------------------------------------------------------------------ closing

    def close(self, reason: str = "the bridge ended") -> None:
        """Stop the robot (``reason``), release it, undeclare everything. Idempotent."""
        with self._cond:
            if self._closed:
                return
            self._closed = True
        self._loop.close(timeout=5.0)
        self._do_stop(reason, release=True, always=True)
        for entity in (self._requests, self._queryable, self._tokens, self._events):
            undeclare(entity)

    # ------------------------------------------------------------------ zenoh callbacks

    def _on_token(self, sample: zenoh.Sample) -> None:
        try:
            name = holder_of(sample.key_expr, self.robot, "alive")
        except ProtocolError:
            return  # not a holder's token (a wildcard): nobody's
        self.alive(name, sample.kind == _PUT)

    def acquire(self, holder: str) -> dict[str, Any]:
        """Take the robot for ``holder`` as its acquire request would (granted only when the
        robot is free or ``holder``'s already): for a controller the bridge itself
        authenticates, a ROS 2 publisher (:mod:`robocli.bridge.ros2`). The reply's dict."""
        return self._acquire(check_name(holder, "holder"))

    def alive(self, name: str, up: bool) -> None:
        """``name``'s liveliness came (``up``) or went: a holder's robocli token, or what
        stands for it (a ROS 2 publisher's graph token). A holder that goes is released."""
        with self._cond:
            if up:
                self._alive.add(name)
                if name == self.holder:
                    self._token_seen = True
            else:
                self._alive.discard(name)
                if name == self.holder:
                    self._pending.append((f"the controller {name} left (its liveliness "
                                          "token went)", True))  # fmt: skip
            self._loop.wake()

    def _on_query(self, query: zenoh.Query) -> None:
        """Answer a control request; every query gets a reply, an error one when refused."""

        def work() -> dict[str, Any]:
            key = str(query.key_expr)
            holder = None if key == control_key(self.robot) else holder_of(
                key, self.robot, "request")  # fmt: skip
            raw = query.payload
            request = decode(raw.to_bytes(), "control request") if raw is not None else {}
            return self._answer(request, holder)

        answer(query, work, "control request", self.robot)

    def _answer(self, request: dict[str, Any], holder: str | None) -> dict[str, Any]:
        """``holder``: who the request's key names (None: the status key, which only tells)."""
        op = request.get("op", "status")
        if op == "status":
            return {"holder": self.holder}
        if holder is None:
            raise RobocliError(
                f"control request: {text(request, 'op', 'control request')} is "
                f"asked on {holder_key(self.robot, 'NAME', 'request')}, as NAME"
            )
        if op == "acquire":
            return self._acquire(holder)
        if op == "release":
            with self._cond:
                mine = holder == self.holder
            if mine:
                self._do_stop(f"released by {holder}", release=True, always=True)
            return {"holder": self.holder, "released": mine}
        raise RobocliError(
            f"control request: op {str(op)[:32]!r} is not acquire, release or status"
        )

    def _acquire(self, holder: str) -> dict[str, Any]:
        with self._robot_lock:
            with self._cond:
                current = self.holder
                if self._closed or (current is not None and current != holder):
                    self.counts["refusals"] += 1
                    why = ("the bridge is closing" if self._closed else
                           f"{self.robot} is held by {current}")  # fmt: skip
                    refused = {"granted": False, "holder": current, "reason": why}
                else:
                    refused = None
                    self.holder = holder
                    self._token_seen = holder in self._alive
                    self._granted_at = time.monotonic()
                    self._last_command = self._granted_at
                    self._stopped_at = self.epoch  # a new holder starts from a stop
                    self.counts["grants"] += 1
                    epoch = self.epoch
            if refused is not None:
                self.event("refused", holder=current, refused=holder, reason=refused["reason"])
                return refused
            if current != holder and self._grant is not None:
                try:
                    self._grant(holder)
                except Exception as exc:
                    with self._cond:
                        self.holder = None
                    reason = f"{self.robot} cannot be driven: {exc}"
                    self.event("refused", holder=None, refused=holder, reason=reason)
                    return {"granted": False, "holder": None, "reason": reason}
        log.info("%s: %s holds the robot", self.robot, holder)
        self.event("granted", holder=holder, epoch=epoch)
        return {"granted": True, "holder": holder, "epoch": epoch}

    # ------------------------------------------------------------------ the gate's thread

    def _step(self) -> float:
        """Apply the stop rule due now, if any; the seconds until one may be due (woken
        sooner by a command or a token). A stop that raises never ends this loop."""
        with self._cond:
            if self._closed:
                return 1.0  # close() is stopping the loop, and stops the robot itself
            action = self._due(time.monotonic())
            if action is None:
                return self._wait(time.monotonic())
        self._do_stop(*action)
        return 0.0

    def _due(self, now: float) -> tuple[str, bool] | None:
        """(reason, release) of the stop due now, or None (called under the condition)."""
        if self._pending:
            return self._pending.pop(0)
        if self.holder is None:
            return None
        if not self._token_seen and now >= self._granted_at + self.token_wait:
            return (f"the controller {self.holder} declared no liveliness token within "
                    f"{self.token_wait:g} s", True)  # fmt: skip
        if self._moving and self.silence is not None and now >= self._last_command + self.silence:
            self._moving = False
            return (f"no command from {self.holder} for {self.silence:g} s", False)
        return None

    def _wait(self, now: float) -> float:
        due = math.inf
        if self.holder is not None and not self._token_seen:
            due = self._granted_at + self.token_wait
        if self.holder is not None and self._moving and self.silence is not None:
            due = min(due, self._last_command + self.silence)
        return max(0.001, min(1.0, due - now))

    def _do_stop(self, reason: str, release: bool, always: bool = False) -> None:
        """Stop the robot (and release its holder); a stop that raises is logged, counted."""
        with self._robot_lock:
            with self._cond:
                holder = self.holder
                if release:
                    self.holder = None
                    self._token_seen = False
                self._moving = False
                self.epoch += 1  # what was commanded before this stop is stale now
                epoch = self.epoch
            if holder is None and not always:
                return
            try:
                self._stop(reason)
            except Exception as exc:
                self.counts["stop_errors"] += 1
                log.error("%s: stopping (%s) failed: %s", self.robot, reason, exc)
                self.event("fault", holder=holder, reason=f"stopping failed: {exc}")
            else:
                self.counts["stops"] += 1
                log.info("%s: stopped: %s", self.robot, reason)
        self.event("released" if release and holder else "stopped", holder=holder,
                   reason=reason, epoch=epoch)  # fmt: skip


__all__ = ["DEFAULT_SILENCE_S", "DEFAULT_TOKEN_WAIT_S", "ControlGate", "answer"]
