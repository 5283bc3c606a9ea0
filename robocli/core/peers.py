"""Benchmark peers in C: the loopback TCP round-trip floor (:class:`PingPong`,
:func:`pingpong_floor`), each end optionally pinned to a CPU, and :class:`Responder`, a
minimal ARCOS server answering frames from a canned table."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from robocli._core import ffi, lib
from robocli.closing import Closing
from robocli.errors import TransportError

if TYPE_CHECKING:
    import numpy as np
    import numpy.typing as npt


def pin_supported() -> bool:
    """Whether threads can be pinned to a CPU here (Linux); elsewhere every ``cpu`` argument
    below must be None."""
    return bool(lib.rc_pin_supported())


def _cpu_arg(cpu: int | None) -> int:
    if cpu is None:
        return -1
    if cpu < 0:
        raise ValueError("cpu must be >= 0 (or None: not pinned)")
    if not pin_supported():
        raise ValueError("this platform cannot pin threads to a CPU; pass cpu=None")
    return cpu


class PingPong(Closing):
    """The machine's floor for request/acknowledge round trips: ``msg_size``-byte ping-pongs
    over one loopback TCP connection (TCP_NODELAY) between a C echo thread, pinned to
    ``echo_cpu``, and the thread that calls :meth:`run`, pinned to ``cpu`` for the call.

    The connection and the echo thread persist between calls, so a long measurement can run
    in short chunks and stay interruptible. Use as a context manager, or call :meth:`close`.
    """

    def __init__(self, msg_size: int = 16, echo_cpu: int | None = None) -> None:
        if not 0 < msg_size <= 65536:
            raise ValueError("msg_size must be 1..65536")
        ptr = lib.rc_pingpong_new(msg_size, _cpu_arg(echo_cpu))
        if ptr == ffi.NULL:
            raise TransportError("loopback ping-pong could not start (sockets or threads)")
        self._p: Any = ffi.gc(ptr, lib.rc_pingpong_free)
        self.msg_size = msg_size
        self.echo_cpu = echo_cpu

    def run(self, n: int, cpu: int | None = None) -> npt.NDArray[np.float64]:
        """``n`` round trips (seconds each) from this thread, pinned to ``cpu`` for the call
        (the previous affinity is restored). Releases the GIL while it runs."""
        import numpy as np

        if n <= 0:
            raise ValueError("n must be positive")
        if self._p is None:
            raise TransportError("ping-pong is closed")
        out = np.empty(n, dtype=np.float64)
        rc = lib.rc_pingpong_run(self._p, n, _cpu_arg(cpu), ffi.from_buffer("double[]", out))
        if rc == -2:
            raise ValueError(f"cannot pin to CPU {cpu} (echo CPU {self.echo_cpu})")
        if rc != 0:
            raise TransportError("loopback ping-pong failed")
        return out

    def close(self) -> None:
        """End the echo thread and close the sockets (bounded: the echo sees end of stream)."""
        if self._p is not None:
            ffi.release(self._p)  # runs rc_pingpong_free now
            self._p = None


def pingpong_floor(
    n: int = 1000, msg_size: int = 16, cpu: int | None = None, echo_cpu: int | None = None
) -> npt.NDArray[np.float64]:
    """Round-trip times (seconds) of ``n`` ping-pongs of :class:`PingPong` (ends pinned to
    ``cpu`` and ``echo_cpu``, or left to the scheduler). Raises
    :class:`~robocli.errors.TransportError` if sockets fail or the platform has no POSIX
    threads."""
    if n <= 0 or msg_size <= 0:
        raise ValueError("n and msg_size must be positive")
    with PingPong(msg_size, echo_cpu) as pp:
        return pp.run(n, cpu)


@dataclass(frozen=True)
class ResponderStats:
    """Counters of a :class:`Responder` since it started."""

    connections: int
    frames: int
    replies: int
    pin_failed: bool


class Responder(Closing):
    """A minimal ARCOS responder in C on 127.0.0.1: for every complete ARCOS frame whose
    payload (type byte + data) is a key of ``table`` it writes that key's reply bytes
    (already framed); other frames get no reply. One client at a time, in a C thread pinned
    to ``cpu`` (None: not pinned). It isolates a client's own cost in a round trip.

    At most 256 entries; keys 1..4096 bytes, replies 0..4096 bytes.
    """

    def __init__(self, table: dict[bytes, bytes], cpu: int | None = None) -> None:
        if len(table) > 256:
            raise ValueError("at most 256 table entries")
        for key, reply in table.items():
            if not 0 < len(key) <= 4096 or len(reply) > 4096:
                raise ValueError("keys must be 1..4096 bytes, replies at most 4096 bytes")
        keys, replies = list(table), list(table.values())
        ptr = lib.rc_responder_new(
            b"".join(keys),
            ffi.new("size_t[]", [len(k) for k in keys] or [0]),
            b"".join(replies),
            ffi.new("size_t[]", [len(r) for r in replies] or [0]),
            len(keys),
        )
        if ptr == ffi.NULL:
            raise MemoryError("cannot allocate the responder table")
        self._r: Any = ffi.gc(ptr, lib.rc_responder_free)
        port = int(lib.rc_responder_start(self._r, _cpu_arg(cpu)))
        if port <= 0:
            raise TransportError("ARCOS responder could not listen on loopback")
        self.port = port
        self.cpu = cpu
        self._stats = ffi.new("rc_responder_stats *")
        self._final = ResponderStats(0, 0, 0, False)

    @property
    def url(self) -> str:
        """``tcp://127.0.0.1:PORT`` of the listening socket."""
        return f"tcp://127.0.0.1:{self.port}"

    @property
    def stats(self) -> ResponderStats:
        """The counters (after :meth:`close`: their final values)."""
        if self._r is None:
            return self._final
        lib.rc_responder_get_stats(self._r, self._stats)
        s = self._stats
        return ResponderStats(int(s.connections), int(s.frames), int(s.replies), bool(s.pin_failed))

    def close(self) -> None:
        """Stop the thread (within ~0.1 s; ~1 s if the peer stopped reading) and close."""
        if self._r is not None:
            lib.rc_responder_stop(self._r)
            self._final = self.stats
            ffi.release(self._r)  # rc_responder_free
            self._r = None
