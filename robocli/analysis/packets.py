"""A session's packets, named and decoded, in time order: :class:`Packet` is one of them and
:class:`PacketLog` orders what the links' reader threads see and hands each packet, once
decoded, to a callback (and to a ``.jsonl`` capture being written)."""

from __future__ import annotations

import contextlib
import heapq
import itertools
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from robocli.io.capture import CaptureWriter

__all__ = ["REORDER", "WIRE_DIR", "Decode", "Line", "Packet", "PacketLog"]

#: How long a packet waits for older ones from another thread before it is handed on (s).
REORDER = 0.05
#: The capture files' names of the directions: client to device, and back.
WIRE_DIR = {"tx": "c2s", "rx": "s2c"}


@dataclass(frozen=True)
class Line:
    """One line on the wire (without its LF) and what it is (a SCIP block's lines)."""

    text: str
    what: str


@dataclass
class Packet:
    """One frame of a session, named and decoded."""

    t: float | None  #: seconds since the session's start (None: a raw capture says no time)
    direction: str  #: "tx" (client to device) or "rx" (device to client)
    name: str  #: what the protocol calls it ("SIP", "JOINT_FEEDBACK", "SENSOR_DATA"...)
    fields: dict[str, Any]  #: decoded fields, in the protocol's units
    frame: bytes  #: the whole frame as on the wire
    port: str | None = None  #: an arm's "motion" or "state" port
    type: int | None = None  #: the ARCOS packet type
    lines: tuple[Line, ...] = field(default=())  #: SCIP: each line of the block, described

    @property
    def wire_dir(self) -> str:
        """``c2s`` or ``s2c``, as capture files and JSON say it."""
        return WIRE_DIR.get(self.direction, self.direction)


#: ``decode(direction, frame, t) -> Packet``: one protocol's namer of a frame.
Decode = Callable[[str, bytes, "float | None"], Packet]


class PacketLog:
    """Packets decoded by ``decode`` and handed to ``emit`` in time order, until ``count``
    of them (0: no end). Reader threads put frames with :meth:`listener`; :meth:`pump`
    hands on those older than :data:`REORDER` s, :meth:`drain` the rest. At most ``bound``
    frames wait (0: no bound); one that finds the queue full is lost and counted in
    :attr:`dropped` (a reader thread never waits for a slow ``emit``). ``writer``: a
    capture that records each packet handed on."""

    def __init__(self, decode: Decode, emit: Callable[[Packet], None], *, count: int = 0,
                 writer: CaptureWriter | None = None, bound: int = 0) -> None:  # fmt: skip
        self.decode, self.emit, self.count, self.writer = decode, emit, count, writer
        #: Unix time (s) of ``t`` 0, once known
        self.epoch: float | None = None
        self.emitted = 0
        self.dropped = 0
        #: what ``emit`` raised in a reader thread (see :meth:`direct`), raised by :meth:`check`
        self.error: Exception | None = None
        self.stopped = threading.Event()  #: set once ``count`` is reached or ``emit`` failed
        self._zero = time.monotonic()
        self._heap: list[tuple[float, int, str, bytes]] = []
        self._seq = itertools.count()
        self._queue: queue.Queue[tuple[str, bytes, float]] = queue.Queue(bound)
        self._lock = threading.Lock()

    def start(self, unix_time: float | None) -> None:
        """Say when ``t`` 0 is (Unix time, s), once; a capture being written says it too."""
        if self.epoch is None and unix_time is not None:
            self.epoch = unix_time
            if self.writer is not None:
                self.writer.begin(unix_time)

    def open(self) -> None:
        """Make the capture file being written (if any): the session is connected, and a
        session that failed to connect writes none."""
        if self.writer is not None:
            self.writer.open()

    def close(self) -> None:
        """Close the capture file being written (if any)."""
        if self.writer is not None:
            self.writer.close()

    def start_now(self) -> None:
        """``t`` 0 is now, for the frames that :meth:`listener` takes."""
        self._zero = time.monotonic()
        self.start(time.time())

    def stamp(self, t: float | None) -> dict[str, float | None]:
        """``t`` (Unix time, when known) and ``t_rel`` (seconds since the start)."""
        return {"t": None if t is None or self.epoch is None else self.epoch + t, "t_rel": t}

    @property
    def done(self) -> bool:
        """True once ``count`` packets were handed on (never with ``count`` 0)."""
        return bool(self.count) and self.emitted >= self.count

    def put(self, packet: Packet) -> None:
        """Record ``packet`` (when a capture is written) and hand it on now."""
        if self.writer is not None:
            self.writer.write(packet.t or 0.0, packet.direction, packet.frame, packet.port)
        self.emit(packet)
        self.emitted += 1

    def show(self, direction: str, frame: bytes, t: float | None) -> None:
        """Decode one frame and hand it on now."""
        self.put(self.decode(direction, frame, t))

    def listener(self, port: str = "") -> Callable[[str, bytes, float], None]:
        """A link's listener ``(direction, frame, t)`` (``t`` on :func:`time.monotonic`):
        the frame waits for :meth:`pump`; with ``port``, its direction is ``"tx:motion"``."""

        def put(direction: str, frame: bytes, t: float) -> None:
            try:
                item = (f"{direction}:{port}" if port else direction, frame, t - self._zero)
                self._queue.put_nowait(item)
            except queue.Full:
                self.dropped += 1

        return put

    def direct(self, direction: str, frame: bytes, t: float | None) -> None:
        """Like :meth:`show`, from a reader thread that gives frames in order, one at a
        time: what ``emit`` raises stops the log (:meth:`check` raises it)."""
        if self.stopped.is_set():
            return
        try:
            with self._lock:
                self.show(direction, frame, t)
        except Exception as exc:  # the caller's: raised in its own thread by check()
            self.error = exc
        if self.error is not None or self.done:
            self.stopped.set()

    def check(self) -> None:
        """Raise what ``emit`` raised in a reader thread, if it did."""
        if self.error is not None:
            raise self.error

    def pump(self) -> None:
        """Take what comes within :data:`REORDER` s; hand on what is older than that."""
        self._take(REORDER)
        self._flush(before=time.monotonic() - self._zero - REORDER)

    def drain(self) -> None:
        """Hand on everything still queued, in time order."""
        self._take()
        self._flush()

    def follow(self, check: Callable[[], None]) -> None:
        """:meth:`pump` until ``count``, calling ``check`` between (it raises when a link
        ended); :meth:`drain` the rest once the links are closed."""
        while not self.done:
            self.pump()
            check()

    def _take(self, wait: float = 0.0) -> None:
        with contextlib.suppress(queue.Empty):
            if wait:
                self._push(*self._queue.get(timeout=wait))
            while True:
                self._push(*self._queue.get_nowait())

    def _push(self, direction: str, frame: bytes, t: float) -> None:
        heapq.heappush(self._heap, (t, next(self._seq), direction, frame))

    def _flush(self, before: float = float("inf")) -> None:
        heap = self._heap
        while heap and heap[0][0] < before and not self.done:
            t, _, direction, frame = heapq.heappop(heap)
            self.show(direction, frame, t)
