"""The client machinery every robocli device is built on: one link to one robot.

A :class:`Session` owns a transport and a framer and gives a device:

- **a reader thread** for unsolicited frames (SIPs, state streams, pushed samples);
- **request/reply read by the caller itself** (leader/follower): :meth:`Session.request`
  takes the read side, writes the request and reads until the reply, handling every other
  frame that arrives meanwhile exactly as the reader thread would. No thread hands the
  reply over, which keeps a round trip near the machine's floor;
- **listeners** (:class:`~robocli.devices.listeners.Listeners`) that see every frame sent and
  received. A listener that raises is isolated: the first failure of each listener is logged
  with its traceback, every failure is counted in
  :attr:`~robocli.devices.stats.LinkStats.listener_errors`, the listener stays registered,
  and the thread that called it goes on. A printing listener whose pipe closed cannot stop
  the keep-alive that keeps a robot safe;
- **periodic tasks** (:class:`~robocli.devices.tasks.PeriodicTask`) that sleep on an event
  until they are due, in the manner of python-can's cyclic send tasks: keep-alives,
  supervisors, dead-man checks;
- **writes with a deadline** (:attr:`Transport.write_timeout`, 1 s by default);
- **a close that always finishes**: :meth:`Session.close` sends the device's stop sequence
  from a ``finally``, within ``close_timeout`` seconds in all, shuts the transport down even
  when another thread holds the write side, joins every thread and says which would not stop.

**Failing closed.** A robocli error in a client thread (link lost, silence, a write past its
deadline) and any unexpected exception there (a bug) end the session: the device's
emergency stop is sent (best effort, bounded), every waiting caller is woken, and the next
call on the device raises that error, with its traceback for a bug. A frame that does not
decode (:class:`~robocli.errors.ProtocolError`) is counted in
:attr:`~robocli.devices.stats.LinkStats.decode_errors` and logged (the first with its
traceback); the session goes on.

This module holds the :class:`Session` (reader, request/reply, failing and closing); its
parts have their own: :mod:`robocli.devices.sending` (the writes and the stop sequence),
:mod:`robocli.devices.listeners`, :mod:`robocli.devices.tasks` and
:mod:`robocli.devices.stats` (the link's counters). All of them are importable from here.
"""

from __future__ import annotations

import logging
import os
import select
import threading
import time
from collections.abc import Callable, Sequence

from robocli.core import Framer
from robocli.devices.listeners import FrameListener, Listeners
from robocli.devices.sending import Sending
from robocli.devices.stats import LinkStats
from robocli.devices.tasks import PeriodicTask
from robocli.errors import ConnectionLost, ProtocolError, RobocliError, TimeoutError
from robocli.transports import Transport

log = logging.getLogger("robocli.devices.session")

#: How long the reader thread waits for bytes before it looks at its stop flag again
#: (a closed socket wakes it at once; a closed serial port may not).
_READER_POLL_S = 0.25
#: The reader stays parked this long after the last caller read its own reply, so that a
#: loop of requests keeps it out of the way, and looks again this often while parked.
_LEADER_LINGER = 0.002
_PARK_S = 0.005
#: Raw bytes kept before the first frame, to show why a server refused the link.
_RAW_TAIL = 512


class Session(Sending):
    """One link to one robot. See the module docstring for the guarantees.

    ``on_frame(frame, t)`` is the device's handler of every received frame (in whichever
    thread read it: the reader, or a caller waiting for a reply). ``name_of(payload,
    direction)`` names packets for the statistics; ``payload_of(frame)`` strips the framing
    for listeners. ``emergency_stop`` gives the packets that stop the robot at once (sent when
    a client thread fails); :meth:`close` takes the full stop sequence.
    """

    def __init__(
        self,
        transport: Transport,
        framer: Framer,
        *,
        on_frame: Callable[[bytes, float], None],
        payload_of: Callable[[bytes], bytes] = bytes,
        name_of: Callable[[bytes, str], str] = lambda payload, direction: "frame",
        emergency_stop: Callable[[], Sequence[bytes]] = tuple,
        stats: LinkStats | None = None,
        close_timeout: float = 2.0,
        name: str = "session",
    ) -> None:
        self.transport = transport
        self.framer = framer
        self.stats = stats if stats is not None else LinkStats()
        self.stats.framer = framer
        self.listeners: Listeners[FrameListener] = Listeners(self.stats, transport.url)
        self.close_timeout = close_timeout
        self.name = name
        #: notified whenever a frame was handled or the session failed; devices wait on it
        self.cond = threading.Condition()
        #: monotonic time the last write began (its bytes left then or later): the silence a
        #: robot's watchdog may have seen is at most the time since
        self.last_tx = time.monotonic()
        self.error: BaseException | None = None
        self.stuck_threads: list[str] = []
        #: the device's handler of every received frame (settable until :meth:`start`)
        self.on_frame = on_frame
        #: called with the monotonic time of every packet sent (a device's own statistics,
        #: cheaper than a listener that sees every frame); must not raise
        self.on_sent: Callable[[float], None] | None = None
        #: ``before_send(packets, seconds since the last write began)`` -> the packets to
        #: write instead (a stop in place of stale set-points after a stall past the robot's
        #: watchdog); under the write lock right before each write of :meth:`send`,
        #: :meth:`send_many`, :meth:`request`, and after it with no packets. Must not raise
        self.before_send: Callable[[Sequence[bytes], float], Sequence[bytes]] | None = None
        #: the robot's watchdog (s): bytes ``before_send`` judged never begin to leave later
        #: than this after the last write began
        self.silence_limit: float | None = None
        self._payload_of = payload_of
        self._name_of = name_of
        self._emergency_stop = emergency_stop
        self._read_lock = threading.Lock()
        #: held from the silence check through the write to the stamp of :attr:`last_tx`
        self._tx_lock = threading.Lock()
        self._leaders = 0  # callers reading their replies right now
        self._leader_lock = threading.Lock()
        self._leader_end = 0.0  # monotonic time the last one finished
        self._reader_polling = False
        self._parked = threading.Event()  # set only to end the session: wakes a parked reader
        self._wake_r: int | None = None
        self._wake_w: int | None = None
        self._closing = False
        self._close_lock = threading.Lock()
        self._tasks: list[PeriodicTask] = []
        self._reader: threading.Thread | None = None
        self._raw_tail: bytearray | None = bytearray()
        self._decode_logged = False

    # ------------------------------------------------------------------ state

    @property
    def alive(self) -> bool:
        """True until the session failed or began closing."""
        return self.error is None and not self._closing

    @property
    def closing(self) -> bool:
        return self._closing

    def check(self) -> None:
        """Raise the error that ended the session, or :class:`ConnectionLost` once closed."""
        if self.error is not None:
            raise self.error
        if self._closing:
            raise ConnectionLost(f"{self.transport.url}: the connection is closed")

    def raw_tail(self) -> bytes:
        """The raw bytes read before the first frame (what a refusing server said)."""
        return bytes(self._raw_tail or b"")

    # ------------------------------------------------------------------ threads

    def start(self) -> None:
        """Start the reader thread and every task added so far."""
        self._raw_tail = None
        if self.transport.fileno() is not None:
            self._wake_r, self._wake_w = os.pipe()
            os.set_blocking(self._wake_r, False)
            os.set_blocking(self._wake_w, False)
        self._reader = threading.Thread(
            target=self._read_loop, name=f"{self.name}-reader", daemon=True
        )
        self._reader.start()
        for task in self._tasks:
            task.start()

    def add_task(self, name: str, step: Callable[[], float]) -> PeriodicTask:
        """A :class:`PeriodicTask` of this session (started by :meth:`start`, or now if the
        session runs); its exceptions fail the session closed."""
        task = PeriodicTask(f"{self.name}-{name}", step, self.fail)
        self._tasks.append(task)
        if self._reader is not None:
            task.start()
        return task

    # ------------------------------------------------------------------ writing

    # ------------------------------------------------------------------ reading

    def request(
        self,
        packet: bytes | None,
        match: Callable[[bytes], bool],
        timeout: float,
    ) -> bytes:
        """Send ``packet`` (if any) and return the first frame for which ``match`` is true,
        reading the link in this thread. Frames that arrive meanwhile are handled as usual.
        Raises :class:`TimeoutError` after ``timeout`` seconds, or the session's error."""
        deadline = time.monotonic() + timeout
        self.check()
        with self._leader_lock:  # the reader parks while callers lead (no GIL contention)
            self._leaders += 1
        if self._reader_polling:
            self._wake_reader()
        read_lock = self._read_lock
        if not (read_lock.acquire(False) or read_lock.acquire(timeout=max(0.0, timeout))):
            self._leader_done()
            raise TimeoutError(f"{self.transport.url}: the link stayed busy for {timeout:g} s")
        try:
            if packet is not None:
                self._send((packet,), min(timeout, self.transport.write_timeout))
            while True:
                if self.error is not None or self._closing:
                    self.check()
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(f"{self.transport.url}: no reply within {timeout:g} s")
                reply = self._read_once(left, match)
                if reply is not None:
                    return reply
        finally:
            read_lock.release()
            self._leader_done()

    def _leader_done(self) -> None:
        with self._leader_lock:
            self._leader_end = time.monotonic()
            self._leaders -= 1

    def _wake_reader(self) -> None:
        if self._wake_w is not None:
            try:
                os.write(self._wake_w, b"\0")
            except (BlockingIOError, OSError):
                pass  # a wake is already pending, or the session is closing

    def _read_once(
        self, timeout: float, match: Callable[[bytes], bool] | None = None
    ) -> bytes | None:
        """Read what arrives within ``timeout`` and handle it (hold ``_read_lock``).
        Returns the first frame ``match`` accepts."""
        try:
            data = self.transport.read(65536, timeout)
        except ConnectionLost as exc:
            url = self.transport.url
            why = ConnectionLost(f"{url}: link lost ({str(exc).removeprefix(f'{url}: ')})")
            self.fail(why)
            raise why from None
        if not data:
            return None
        now = time.monotonic()
        if self._raw_tail is not None:
            self._raw_tail += data
            del self._raw_tail[:-_RAW_TAIL]
        reply = None
        payload_of, name_of, count = self._payload_of, self._name_of, self.stats.count_received
        listeners, on_frame = self.listeners, self.on_frame
        for frame in self.framer.feed(data):
            payload = payload_of(frame)
            count(name_of(payload, "rx"))
            if listeners._items:
                listeners.notify("rx", payload, now)
            try:
                on_frame(frame, now)
            except ProtocolError as exc:
                self._decode_failed(exc)
            if reply is None and match is not None and match(frame):
                reply = frame
        return reply

    def _decode_failed(self, exc: ProtocolError) -> None:
        """A received frame did not decode: count it, log the first with its traceback."""
        self.stats.add("decode_errors")
        if not self._decode_logged:
            self._decode_logged = True
            log.warning("%s: %s (later ones only counted)", self.transport.url, exc,
                        exc_info=True)  # fmt: skip
        else:
            log.debug("%s: %s", self.transport.url, exc)

    def _read_loop(self) -> None:
        """Handle unsolicited frames while no caller holds the read side.

        While callers read their own replies (and for ``_LEADER_LINGER`` s after the last
        one), the reader parks instead of polling the link: otherwise every reply would wake
        it, and it would take the GIL from the very caller waiting for that reply."""
        fd = self.transport.fileno()
        wake = self._wake_r
        poller = None
        if fd is not None and wake is not None:
            poller = select.poll()
            poller.register(fd, select.POLLIN)
            poller.register(wake, select.POLLIN)
        try:
            while not self._closing and self.error is None:
                if self._leaders or time.monotonic() - self._leader_end < _LEADER_LINGER:
                    self._parked.wait(_PARK_S)
                    continue
                self._reader_polling = True
                if self._leaders:  # a caller began leading as we were about to poll
                    self._reader_polling = False
                    continue
                if poller is not None and wake is not None:
                    events = poller.poll(_READER_POLL_S * 1000)
                    ready = any(ev_fd == fd for ev_fd, _ in events)
                    if any(ev_fd == wake for ev_fd, _ in events):
                        _drain_pipe(wake)
                else:
                    ready = self.transport.wait_readable(_READER_POLL_S)
                self._reader_polling = False
                if not ready or not self._read_lock.acquire(blocking=False):
                    continue  # nothing yet, or a caller leads: it handles what arrives
                try:
                    if not self._closing:
                        self._read_once(0)
                finally:
                    self._read_lock.release()
        except RobocliError as exc:
            if not self._closing:
                self.fail(exc)
        except BaseException as exc:
            self.fail(exc)

    # ------------------------------------------------------------------ failing, closing

    def fail(self, exc: BaseException) -> None:
        """End the session with ``exc`` (first error wins): stop the robot (best effort,
        bounded), wake every waiter. Callable from any thread; idempotent."""
        with self.cond:
            if self.error is not None or self._closing:
                self.cond.notify_all()
                return
            self.error = exc
            self.cond.notify_all()
        if isinstance(exc, RobocliError):
            log.error("%s", exc)
        else:
            log.error("%s: client thread failed", self.transport.url, exc_info=exc)
        for task in self._tasks:
            task.stop()
        self._try_send(self._emergency_stop(), time.monotonic() + 0.5)

    def close(self, stop_sequence: Sequence[bytes] = ()) -> bool:
        """Send ``stop_sequence``, then shut the link down and join the threads, all within
        ``close_timeout`` seconds. Returns True when the whole stop sequence went out.
        Idempotent; safe from any thread, including a listener or a task."""
        with self._close_lock:
            if self._closing:
                return False
            self._closing = True
        deadline = time.monotonic() + self.close_timeout
        sent = False
        me = threading.current_thread()
        try:
            for task in self._tasks:
                task.stop()
            # a task may be mid-write (a keep-alive re-sending a set-point): let it finish,
            # so that nothing it sends lands after the stop sequence
            for task in self._tasks:
                if task.thread is not me and task.thread.is_alive():
                    task.thread.join(
                        max(0.0, deadline - 0.6 * self.close_timeout - time.monotonic())
                    )
            # the link may be dead already: still try, every write is bounded
            sent = self._try_send(stop_sequence, deadline - 0.2 * self.close_timeout)
        finally:
            self.transport.close()  # never waits for a blocked writer; wakes the reader
            self._parked.set()
            self._wake_reader()
            with self.cond:
                self.cond.notify_all()
            threads = [t.thread for t in self._tasks] + ([self._reader] if self._reader else [])
            for thread in threads:
                if thread is me or not thread.is_alive():
                    continue
                thread.join(max(0.05, deadline - time.monotonic()))
                if thread.is_alive():
                    self.stuck_threads.append(thread.name)
                    log.warning("%s: thread %s did not stop", self.transport.url, thread.name)
            if not self.stuck_threads:
                for pipe_fd in (self._wake_r, self._wake_w):
                    if pipe_fd is not None:
                        os.close(pipe_fd)
                self._wake_r = self._wake_w = None
        return sent


def _drain_pipe(fd: int) -> None:
    try:
        while os.read(fd, 64):
            pass
    except (BlockingIOError, OSError):
        pass


__all__ = ["FrameListener", "LinkStats", "Listeners", "PeriodicTask", "Session"]
