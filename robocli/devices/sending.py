"""The write side of a :class:`~robocli.devices.session.Session`: writes with a deadline,
race-free against a stall (the robot's watchdog), and the bounded stop sequence of a failing
or closing session. Part of :mod:`robocli.devices.session` (import from there).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Sequence
from typing import NoReturn

from robocli.devices.listeners import FrameListener, Listeners
from robocli.devices.stats import LinkStats
from robocli.errors import ConnectionLost, RobocliError, StaleWrite, TimeoutError
from robocli.transports import Transport

log = logging.getLogger("robocli.devices.session")

__all__ = ["Sending"]


class Sending:
    """What :class:`~robocli.devices.session.Session` writes with (see its attributes)."""

    transport: Transport
    stats: LinkStats
    listeners: Listeners[FrameListener]
    last_tx: float
    on_sent: Callable[[float], None] | None
    before_send: Callable[[Sequence[bytes], float], Sequence[bytes]] | None
    silence_limit: float | None
    _tx_lock: threading.Lock
    _payload_of: Callable[[bytes], bytes]
    _name_of: Callable[[bytes, str], str]

    def check(self) -> None:
        raise NotImplementedError

    def fail(self, exc: BaseException) -> None:
        raise NotImplementedError

    def send(self, packet: bytes, timeout: float | None = None) -> None:
        """Write one framed packet within ``timeout`` (default: the transport's deadline).
        A lost link or a missed deadline fails the session and raises."""
        self.check()
        self._send((packet,), timeout)

    def send_many(self, packets: Sequence[bytes], timeout: float | None = None) -> None:
        """Write several framed packets in **one** write (as some vendor SDKs do, so that a
        robot sees them together); statistics and listeners still see each packet."""
        self.check()
        self._send(packets, timeout)

    def _send(self, packets: Sequence[bytes], timeout: float | None) -> None:
        """Write ``packets``, race-free against a stall anywhere: the silence check, the write
        and the stamp of :attr:`last_tx` (the time taken *before* the write: a stall after
        the bytes left counts as silence) are one step under ``_tx_lock``. The transport
        gets the latest time the bytes may begin to leave (previous start + ``silence_limit``)
        and sends nothing past it (:class:`StaleWrite`: ``before_send`` judges again, now).
        After each write ``before_send`` is asked again with no packets and the longest
        silence the robot may have seen (a stall inside the write): its stop goes at once.
        Listeners, ``on_sent`` and :meth:`fail` (the emergency stop) run after the lock."""
        limit = self.transport.write_timeout if timeout is None else timeout
        if not self._tx_lock.acquire(timeout=max(0.0, limit)):
            self._write_failed(TimeoutError(
                f"{self.transport.url}: write blocked for {limit:g} s by another write"
            ))  # fmt: skip
        sent: list[tuple[Sequence[bytes], float]] = []
        try:
            failure = self._send_locked(packets, limit, sent)
        finally:
            self._tx_lock.release()
        for done, start in sent:
            self._notify_sent(done, start)
        if failure is not None:
            self._write_failed(failure)

    def _send_locked(
        self, packets: Sequence[bytes], limit: float, sent: list[tuple[Sequence[bytes], float]]
    ) -> RobocliError | None:
        """The writes of :meth:`_send` (``_tx_lock`` held); appends what went out to
        ``sent`` with its start time, returns the error of a write that failed."""
        before, stale = self.before_send, self.silence_limit
        start = time.monotonic()
        previous = self.last_tx
        if before is not None:
            packets = before(packets, start - previous)
        not_after = previous + stale if stale is not None and before is not None else None
        while packets:
            data = packets[0] if len(packets) == 1 else b"".join(packets)
            try:
                self.transport.write(data, limit, not_after=not_after)
            except StaleWrite:  # stalled between the check and the write: judge again
                assert before is not None
                start, not_after = time.monotonic(), None
                packets = before(packets, start - previous)
                continue
            except RobocliError as exc:
                return exc
            self.last_tx = start
            sent.append((packets, start))
            if before is None:
                break
            packets = before((), time.monotonic() - previous)  # stalled inside the write?
            previous, start, not_after = start, time.monotonic(), None
        return None

    def _write_failed(self, exc: RobocliError) -> NoReturn:
        """A write failed or missed its deadline: count it, fail the session, raise."""
        if not isinstance(exc, ConnectionLost):  # the deadline: the peer does not read
            self.stats.add("write_timeouts")
        self.fail(exc)
        raise exc

    def _notify_sent(self, packets: Sequence[bytes], now: float) -> None:
        """Statistics, ``on_sent`` and listeners of packets written at ``now``."""
        payload_of, name_of, count = self._payload_of, self._name_of, self.stats.count_sent
        listeners, on_sent = self.listeners, self.on_sent
        for packet in packets:
            payload = payload_of(packet)
            count(name_of(payload, "tx"))
            if on_sent is not None:
                on_sent(now)
            if listeners._items:
                listeners.notify("tx", payload, now)

    def _try_send(self, packets: Sequence[bytes], deadline: float) -> bool:
        """Write ``packets`` in order until one fails or ``deadline`` passes; ``_tx_lock`` is
        awaited until ``deadline`` only (a stalled writer never holds a stop or :meth:`close`
        longer: close then shuts the transport, which wakes it)."""
        url = self.transport.url
        if not packets:
            return True
        if not self._tx_lock.acquire(timeout=max(0.0, deadline - time.monotonic())):
            log.warning("%s: stop sequence not sent: another write is stuck", url)
            return False
        sent: list[tuple[Sequence[bytes], float]] = []
        try:
            for packet in packets:
                left = deadline - time.monotonic()
                if left <= 0:
                    log.warning("%s: stop sequence cut short by its deadline", url)
                    return False
                start = time.monotonic()
                try:
                    self.transport.write(packet, timeout=left)
                except RobocliError as exc:
                    log.warning("%s: could not send the stop sequence: %s", url, exc)
                    return False
                self.last_tx = start
                sent.append(((packet,), start))
        finally:
            self._tx_lock.release()
            for done, start in sent:
                self._notify_sent(done, start)
        return True
