"""What the Pioneer and arm bridges share: :class:`Bridge`.

A bridge has a name, ends when closed or when its device's link fails (:meth:`Bridge.wait`,
:attr:`Bridge.failure`, a ``fault`` event on the control key), answers ``@info`` with
:meth:`Bridge.info`, puts each sample its device produces until then, and closes in one order:
what comes in is undeclared first, then the gate (which stops the device), then the threads end,
then what goes out is undeclared.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeVar

from robocli.bridge.control import ControlGate
from robocli.closing import Closing
from robocli.errors import RobocliError, TimeoutError
from robocli.zenoh.keys import check_name, topic_key
from robocli.zenoh.robot_keys import control_key, holder_key, reply, undeclare

if TYPE_CHECKING:
    import zenoh

log = logging.getLogger("robocli.bridge")

_S = TypeVar("_S")


class Bridge(Closing):
    """The common part of a device bridge (see the module). A subclass sets :attr:`gate`,
    its threads (``_threads``) and what it declared (``_inbound``: subscribers, queryables
    and the liveliness token; ``_outbound``: publishers and the info queryable)."""

    #: the device in log lines and fault reasons ("robot", "arm")
    device = "device"
    gate: ControlGate
    _threads: list[threading.Thread]
    _inbound: tuple[Any, ...]
    _outbound: tuple[Any, ...]

    def __init__(self, name: str) -> None:
        self.name = check_name(name, "robot name")
        self.failure: BaseException | None = None  #: what ended the device's link, if it ended
        self._done = threading.Event()
        self._closed = False
        self._offset = time.time() - time.monotonic()

    def wait(self, timeout: float | None = None) -> bool:
        """Block until the bridge ends (closed, or the device's link failed: :attr:`failure`)
        or ``timeout`` s pass; True when it ended."""
        return self._done.wait(timeout)

    def info(self) -> dict[str, Any]:
        """What ``robocli/<robot>/@info`` answers."""
        raise NotImplementedError

    def _keys(self, topics: tuple[str, ...], command: str) -> dict[str, str]:
        """The ``keys`` of :meth:`info`: each topic's, the control key, the holder's
        ``command`` key (``<holder>`` as ``*``) and the event key."""
        keys = {topic: topic_key(self.name, topic) for topic in topics}
        keys["control"] = control_key(self.name)
        keys[command] = holder_key(self.name, None, command)
        keys["event"] = control_key(self.name, "event")
        return keys

    def _on_info(self, query: zenoh.Query) -> None:
        reply(query, self.info())

    def _put_each(self, next_sample: Callable[[float], _S], alive: Callable[[], bool],
                  put_one: Callable[[_S], None]) -> None:  # fmt: skip
        """Put each sample ``next_sample(timeout)`` gives until closed or the link fails
        (a timeout while the device is not ``alive``, or any robocli error)."""
        while not self._closed:
            try:
                sample = next_sample(1.0)
            except TimeoutError:
                if alive():
                    continue
                self._fail()
                return
            except RobocliError:
                self._fail()
                return
            put_one(sample)
        self._done.set()

    def _check_link(self) -> str:
        """Raise the error that ended the device's link; else return why it is silent."""
        raise NotImplementedError

    def _fail(self) -> None:
        try:
            silent = self._check_link()
        except RobocliError as exc:
            self.failure = exc
        else:
            self.failure = TimeoutError(silent)
        log.error("%s: the %s's link ended: %s", self.name, self.device, self.failure)
        self.gate.event("fault", holder=self.gate.holder,
                        reason=f"{self.device} link: {self.failure}")  # fmt: skip
        self._done.set()

    def _stop_taking(self) -> None:
        """Between undeclaring what comes in and closing the gate (the arm ends its uploads)."""

    def close(self) -> None:
        """Stop taking commands, stop the device, undeclare everything. Idempotent."""
        if self._closed:
            return
        self._closed = True
        for entity in self._inbound:
            undeclare(entity)
        self._stop_taking()
        self.gate.close("the bridge ended")
        for thread in self._threads:
            thread.join(timeout=5.0)
        for entity in self._outbound:
            undeclare(entity)
        self._done.set()


__all__ = ["Bridge"]
