"""Hokuyo laser scanners over SCIP 2.0: URG-04LX (USB serial), UTM-30LX, UST-10LX (TCP 10940).

>>> with Laser.connect("tcp://192.168.0.10:10940") as laser:   # doctest: +SKIP
...     scan = laser.scan()                  # one scan (GD): ranges (m, NaN = error code)
...     for scan in laser.scans(count=10):   # continuous (MD), stopped with QT on exit
...         print(scan.t, scan.ranges.min())

Connecting does what urg_library does: QT until the sensor answers ``00`` (a one-char status
means SCIP 1.1: it sends ``SCIP2.0``; ``0E`` means time-adjust mode: it sends ``TM2``); MD
frames that a previous client left streaming are skipped and counted
(:attr:`Laser.stale_frames`); a robocli simulator holding another client refuses this one
(:class:`~robocli.errors.DeviceError`, "laser busy"). Then VV, PP and II, the clock offset
with TM0/TM1/TM2 (:meth:`Laser.sync_clock`), and BM turns the laser on.

On the shared :class:`~robocli.devices.session.Session`: a reader thread takes the streamed
frames, every request waits for the reply whose echo is its own line (within ``timeout``),
every line's checksum is checked (``check=False`` skips the data lines' ones, as
urg_library does by default). A streamed frame that does not decode (garbage, a wrong sum,
a truncated block) is dropped and counted (:attr:`Laser.dropped`); the stream goes on with
the next frame. A reply that does not decode raises a typed error
(:class:`~robocli.errors.FramingError`, :class:`~robocli.errors.ChecksumError`); a
refusal raises :class:`~robocli.protocols.scip2.ScipStatusError` with the sensor's code; no
reply raises :class:`~robocli.errors.TimeoutError`. :meth:`Laser.close` always sends QT
(bounded) and closes the link.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Generator, Iterable
from typing import Any

from robocli.addresses import parse_device_url
from robocli.closing import closed_on_error
from robocli.devices import simulators
from robocli.devices.base import (
    ListenerHandle,
    SessionDevice,
    close_simulator,
    deprecated,
    deprecated_listener,
    pick_kind,
)
from robocli.devices.laser.clock import SensorClock
from robocli.devices.laser.scan import LaserInfo, Scan, make_scan
from robocli.devices.listeners import FrameListener, Listeners
from robocli.devices.session import Session
from robocli.devices.stats import LinkStats
from robocli.errors import (
    ConnectionLost,
    DeviceError,
    FramingError,
    InvalidArgument,
    ProtocolError,
    TimeoutError,
)
from robocli.protocols import scip2
from robocli.protocols.common import find_refusal
from robocli.protocols.scip2 import fast
from robocli.transports import Transport, open_transport

__all__ = ["Laser", "ScanListener"]

log = logging.getLogger("robocli.devices.laser")

#: Listener of streamed scans: called in the reader thread with each :class:`Scan`.
ScanListener = Callable[[Scan], None]
QUEUE = 64  #: streamed scans kept for :meth:`Laser.read`; older ones are dropped (counted)
_QT = b"QT\n"
QT_TRIES = 3


def _is_frame(block: bytes) -> bool:
    """An M-type data frame (status 99) rather than a reply."""
    nl = block.find(b"\n")
    return nl >= 2 and block[:1] == b"M" and block[nl + 1 : nl + 3] == b"99"


def _stat_name(payload: bytes, direction: str) -> str:
    return payload[:2].decode("latin-1") if payload[:2].isalnum() else "?"


class Laser(SessionDevice):
    """A connected scanner. Make one with :meth:`connect`; use it as a context manager."""

    def __init__(
        self, transport: Transport, *, timeout: float = 2.0, check: bool = True,
        start: bool = True,
    ) -> None:  # fmt: skip
        """``start``: start the reader thread now. :meth:`connect` starts it after the
        handshake, whose replies it reads in the calling thread: the line a robocli server
        sends before closing a link it refuses is still there to read then."""
        self.timeout = timeout
        self.checksums = check  #: checksums are verified (``check=`` of connect)
        self.clock = SensorClock()
        self.info: LaserInfo | None = None
        self.switched = False  #: the sensor was in SCIP 1.1 and was switched to 2.0
        self.dropped = 0  #: streamed frames that did not decode (garbled, truncated, bad sum)
        self.stale_frames = 0  #: frames of a stream this client did not start (or stopped)
        self.overrun = 0  #: streamed scans dropped because nobody read them
        self.frames = 0  #: streamed scans received
        self._epoch = time.time() - time.monotonic()
        self._queue: deque[Scan] = deque(maxlen=QUEUE)
        self._stream: scip2.ScanEcho | None = None
        self._stream_interval = 0
        self._laser_on = False
        self._lock = threading.Lock()
        self._session = Session(
            transport, fast.reply_framer(), on_frame=self._on_frame,
            name_of=_stat_name, emergency_stop=lambda: (_QT,), name="laser",
        )  # fmt: skip
        self.scan_listeners: Listeners[ScanListener] = Listeners(
            self._session.stats, transport.url
        )  # fmt: skip
        if start:
            self._session.start()

    # ---------------------------------------------------------------- connecting

    @classmethod
    def connect(
        cls,
        url: str,
        *,
        timeout: float = 2.0,
        baudrate: int = 115200,
        laser_on: bool = True,
        sync_samples: int = 5,
        check: bool = True,
        listeners: Iterable[FrameListener] = (),
        listener: FrameListener | None = None,
    ) -> Laser:
        """Open ``url`` (a serial device, a pyserial URL, ``tcp://host:10940``, or
        ``sim://[MODEL][?OPTION=VALUE...]``: the built-in simulator, started in-process on
        loopback and closed with the laser), bring the sensor to SCIP 2.0 and idle, read
        VV/PP/II, estimate the clock offset (``sync_samples`` TM1 round trips; 0: none) and
        turn the laser on. ``listeners`` see every request and reply block from the first
        (``(direction, bytes, t)``); ``listener`` is the deprecated one-listener spelling."""
        if listener is not None:
            deprecated("Laser.connect(listener=)", "Laser.connect(listeners=[...])")
            listeners = (*listeners, listener)
        where = parse_device_url(url, what="laser URL")
        if where.kind == "sim":
            return simulators.connect_to(  # type: ignore[no-any-return]
                "laser", where, lambda sim: cls.connect(
                    sim.url, timeout=timeout, laser_on=laser_on, sync_samples=sync_samples,
                    check=check, listeners=listeners),
            )  # fmt: skip
        if where.kind == "zenoh":
            raise InvalidArgument(f"{url!r}: a laser is reached by its serial port or TCP")
        transport = open_transport(where.target, baudrate=baudrate, timeout=max(timeout, 1.0))
        laser = cls(transport, timeout=timeout, check=check, start=False)
        for one in listeners:
            laser.session.listeners.add(one)
        with closed_on_error(laser):
            laser._handshake()
            laser._session.start()
            laser.info = laser.read_info()
            if sync_samples > 0:
                laser.sync_clock(sync_samples)
            if laser_on:
                laser.laser_on()
        return laser

    def _handshake(self) -> None:
        """QT until the sensor is idle in SCIP 2.0. A robocli simulator that holds another
        client refuses this one with a line (``robocli-refused: laser busy...``) and closes:
        :class:`DeviceError` with its reason, not a lost link."""
        url = self.url
        for _ in range(4):
            try:
                reply = self.request(_QT)
            except TimeoutError:
                raise TimeoutError(
                    f"{url}: no SCIP sensor answered QT within {self.timeout:g} s"
                ) from None
            except ConnectionLost:
                reason = find_refusal(self._session.raw_tail())
                if reason is None:
                    raise
                raise DeviceError(f"{url}: {reason}") from None
            if reply.status == "00":
                return
            if len(reply.status) == 1:  # SCIP 1.1
                if self.request(b"SCIP2.0\n").status != "0":
                    raise ProtocolError(f"{url}: the sensor refused the switch to SCIP 2.0")
                self.switched = True
                log.info("%s: switched from SCIP 1.1 to SCIP 2.0", url)
                continue
            if reply.status == "0E":  # in time-adjust mode
                self.request(b"TM2\n")
                continue
            raise scip2.ScipStatusError("QT", reply.status)
        raise ProtocolError(f"{url}: the sensor did not come to SCIP 2.0 idle")

    def read_info(self) -> LaserInfo:
        """VV, PP and II (VV's sums are not checked: some URG-04LX get SERI's wrong)."""
        vv = scip2.parse_info(self.command("VV").body, check=False)
        pp = scip2.parse_info(self.command("PP").body, check=self.checksums)
        ii = scip2.parse_info(self.command("II").body, check=False)
        return LaserInfo(vv, pp, ii)

    # ---------------------------------------------------------------- requests

    @property
    def url(self) -> str:
        return self._session.transport.url

    @property
    def session(self) -> Session:
        return self._session

    def epoch(self, monotonic: float | None = None) -> float:
        """Host epoch seconds of a monotonic time (default: now), free of wall-clock jumps."""
        return (time.monotonic() if monotonic is None else monotonic) + self._epoch

    def request(self, line: bytes, timeout: float | None = None) -> scip2.Reply:
        """Send a request ``line`` and return its reply (the block echoing the line), not
        checked for its status."""
        block = self._request_block(line, timeout)
        return scip2.parse_reply(block, self.checksums)

    def _request_block(self, line: bytes, timeout: float | None) -> bytes:
        prefix = line.rstrip(b"\r\n") + b"\n"
        n = len(prefix)

        def match(block: bytes) -> bool:
            return block.startswith(prefix) and block[n : n + 2] != b"99"

        return self._session.request(line, match, self.timeout if timeout is None else timeout)

    def command(self, command: str, tag: str | None = None, **params: int) -> scip2.Reply:
        """Send ``command`` with ``params``; its reply, or :class:`ScipStatusError`."""
        reply = self.request(scip2.build_request(command, tag, **params))
        return reply.raise_for_status()

    def laser_on(self) -> None:
        """BM (``02``, already on, is fine)."""
        self.command("BM")
        self._laser_on = True

    def laser_off(self) -> None:
        """QT: stops streaming, laser off."""
        self.stop()

    def reset(self) -> None:
        """RS: laser off, timer to 0 (the clock offset is measured again)."""
        with self._lock:
            self._stream = None
        self.command("RS")
        self._laser_on = False
        self.sync_clock()

    def sync_clock(self, samples: int = 5) -> float:
        """Measure the clock offset with TM0, ``samples`` x TM1, TM2 (the laser goes off:
        turn it on again with :meth:`laser_on`). Not while streaming."""
        if self._stream is not None:
            raise DeviceError("stop streaming before synchronising the clock (TM is refused)")
        self.command("TM", code=0)
        got: list[tuple[float, int, float]] = []
        try:
            for _ in range(samples):
                before = self.epoch()
                reply = self.command("TM", code=1)
                after = self.epoch()
                if len(reply.body) != 1 or len(reply.body[0]) != 5:
                    raise FramingError(f"SCIP TM1 reply {reply.body!r}: expected one time line")
                line = reply.body[0]
                if self.checksums:
                    line = scip2.check_line(line, "TM1 time")
                got.append((before, scip2.decode_value(line[:4]), after))
        finally:
            self.command("TM", code=2)
            self._laser_on = False
        return self.clock.calibrate(got)

    # ---------------------------------------------------------------- scans

    def _range(self, start: int | None, end: int | None) -> tuple[int, int]:
        info = self._info()
        return (info.amin if start is None else start), (info.amax if end is None else end)

    def _info(self) -> LaserInfo:
        if self.info is None:
            self.info = self.read_info()
        return self.info

    def scan(
        self, start: int | None = None, end: int | None = None, cluster: int = 1, *,
        intensity: bool = False, short: bool = False,
    ) -> Scan:  # fmt: skip
        """One scan (GD; GE with ``intensity``; GS with ``short``, 2-char values up to 4.095
        m) over steps ``start..end`` (default AMIN..AMAX), ``cluster`` steps per value."""
        if not self._laser_on:
            self.laser_on()
        first, last = self._range(start, end)
        cmd = "GE" if intensity else "GS" if short else "GD"
        block = self._request_block(
            scip2.build_request(cmd, start=first, end=last, cluster=cluster), None
        )
        received = self.epoch()
        return self._to_scan(fast.decode_scan(block, self.checksums), received, observe=False)

    def _to_scan(self, s: scip2.ScanReply, received: float, *, observe: bool) -> Scan:
        ms = self.clock.unwrap(s.timestamp)
        if observe:
            self.clock.observe(ms, received)
        t = self.clock.to_host(ms)
        return make_scan(
            self._info(), raw=s.ranges, intensities=s.intensities, start=s.start,
            cluster=s.cluster, t=received if t is None else t, stamp_ms=ms, received=received,
            command=s.command, remaining=s.remaining,
        )  # fmt: skip

    def start(
        self, start: int | None = None, end: int | None = None, cluster: int = 1, *,
        interval: int = 0, count: int = 0, intensity: bool = False, short: bool = False,
    ) -> None:  # fmt: skip
        """Start streaming (MD; ME with ``intensity``; MS with ``short``): every
        ``interval + 1``-th scan, ``count`` scans (0: until :meth:`stop`). Read them with
        :meth:`read`, or listen with :meth:`on_scan`."""
        first, last = self._range(start, end)
        cmd = "ME" if intensity else "MS" if short else "MD"
        line = scip2.build_request(
            cmd, start=first, end=last, cluster=cluster, interval=interval, count=count
        )
        with self._lock:
            self._queue.clear()
            self._stream = scip2.parse_scan_echo(line.rstrip(b"\n"))
            self._stream_interval = interval
        try:
            self.request(line).raise_for_status()
        except BaseException:
            with self._lock:
                self._stream = None
            raise
        self._laser_on = True

    def stop(self) -> None:
        """QT: stop streaming (frames still queued in the link are skipped); laser off. A QT
        whose reply does not come is sent again, three times in all, as urg_library does
        (a reply lost on a saturated serial line)."""
        with self._lock:
            self._stream = None
        for attempt in range(QT_TRIES):
            try:
                self.command("QT")
                break
            except TimeoutError:
                if attempt == QT_TRIES - 1:
                    raise TimeoutError(
                        f"{self.url}: the sensor did not answer QT ({QT_TRIES} tries, "
                        f"{self.timeout:g} s each): it may still be streaming"
                    ) from None
                log.info("%s: no reply to QT; sending it again", self.url)
        self._laser_on = False

    @property
    def streaming(self) -> bool:
        return self._stream is not None

    def frame_timeout(self) -> float:
        """How long :meth:`read` waits for a frame: 16 scan periods (as urg_library), plus
        the skipped scans, at least :attr:`timeout`."""
        period = self._info().period
        return max(self.timeout, 16 * period + 2 * period * self._stream_interval)

    def read(self, timeout: float | None = None) -> Scan:
        """The next streamed scan (oldest first); :class:`TimeoutError` if none comes."""
        wait = self.frame_timeout() if timeout is None else timeout
        deadline = time.monotonic() + wait
        cond = self._session.cond
        with cond:
            while not self._queue:
                self._session.check()
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(f"{self.url}: no scan within {wait:g} s")
                if self._stream is None and not self._queue:
                    raise ProtocolError(f"{self.url}: not streaming (start() first)")
                cond.wait(min(left, 0.25))
            return self._queue.popleft()

    def scans(
        self, count: int | None = None, **options: int | bool | None
    ) -> Generator[Scan, None, None]:
        """Stream scans (see :meth:`start` for ``options``), ``count`` of them (None: until
        the loop ends); streaming stops (QT) when the generator ends or is closed. A loop
        left early (``break``, an exception) closes it only when the generator is collected:
        close it yourself (``with contextlib.closing(laser.scans()) as scans:``) so that the
        QT, and the :class:`TimeoutError` of a sensor that does not answer it, happen there."""
        self.start(count=0 if count is None or count > 99 else count, **options)  # type: ignore[arg-type]
        try:
            n = 0
            while count is None or n < count:
                yield self.read()
                n += 1
        finally:
            if self._session.alive:
                self.stop()

    def add_listener(self, listener: Callable[..., None], *, kind: str = "frames"
                     ) -> ListenerHandle:  # fmt: skip
        """Call ``listener`` with what ``kind`` names and return a handle whose ``remove()``
        takes it off: ``"frames"``, ``(direction "tx"/"rx", block, t)`` for every request
        and reply block; ``"scans"``, ``listener(scan)`` for each streamed :class:`Scan`.
        Called in the reader thread; an exception there is counted and logged, never stops
        the stream."""
        return self._add_listener(listener, kind)

    def _listeners_of(self, kind: str) -> Listeners[Any]:
        pick_kind(kind, ("frames", "scans"), "Laser")
        return self._session.listeners if kind == "frames" else self.scan_listeners

    on_scan = deprecated_listener("Laser", "on_scan", "scans")
    remove_scan_listener = deprecated_listener("Laser", "remove_scan_listener", "scans",
                                               remove=True)  # fmt: skip

    @property
    def stats(self) -> LinkStats:
        """The link's counters (``stats.as_dict()``)."""
        return self._session.stats

    def _on_frame(self, block: bytes, now: float) -> None:
        if not _is_frame(block):
            return  # a reply: its caller takes it (a stray one is nobody's)
        stream = self._stream
        if stream is None:
            self.stale_frames += 1
            return
        try:
            s = fast.decode_scan(block, self.checksums)
        except (FramingError, ProtocolError, DeviceError) as exc:
            self.dropped += 1
            log.debug("%s: frame dropped: %s", self.url, exc)
            return
        if (s.command, s.start, s.end, s.cluster) != (
            stream.command, stream.start, stream.end, stream.cluster,
        ):  # fmt: skip
            self.stale_frames += 1
            return
        scan = self._to_scan(s, self.epoch(now), observe=True)
        cond = self._session.cond
        with cond:
            if len(self._queue) == QUEUE:
                self.overrun += 1
            self._queue.append(scan)
            self.frames += 1
            if scan.remaining == 0 and stream.remaining:  # the last of N: the sensor stops
                self._stream = None
                self._laser_on = False
            cond.notify_all()
        if self.scan_listeners._items:
            self.scan_listeners.notify(scan)

    # ---------------------------------------------------------------- closing

    def close(self, stop: bool = True) -> None:
        """Send QT (bounded; ``stop=False``: none, the sensor keeps measuring) and close the
        link; then the simulator of a ``sim://`` URL. Idempotent."""
        with self._lock:
            self._stream = None
        try:
            self._session.close((_QT,) if stop else ())
        finally:
            close_simulator(self)

    #: the in-process simulator of a ``sim://`` URL (None otherwise), closed with the laser
    simulator: simulators.Simulator | None = None
