"""ARCOS checksum and the C framers: complete frames of ARCOS, Simple Message (little- or
big-endian length prefix), ros4mat and SCIP 2.0 in any chunking of a byte stream,
resynchronising one byte at a time after garbage and counting what was dropped."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

from robocli._core import ffi, lib
from robocli.core._buffers import Buffer, _bytes_view

PROTOCOLS = ("arcos", "sm-le", "sm-be", "ros4mat", "scip2")

_PROTO_IDS = {
    "arcos": lib.RC_PROTO_ARCOS,
    "sm-le": lib.RC_PROTO_SM_LE,
    "sm-be": lib.RC_PROTO_SM_BE,
    "ros4mat": lib.RC_PROTO_ROS4MAT,
    "scip2": lib.RC_PROTO_SCIP2,
}


def arcos_checksum(data: Buffer) -> int:
    """ARCOS checksum (0..65535) of the type byte and data of a packet (bytes 3..N)."""
    buf = _bytes_view(data)
    return int(lib.rc_arcos_checksum(buf, len(buf)))


# ---------------------------------------------------------------------------- framers


@dataclass(frozen=True)
class FramerStats:
    """Counters of a :class:`Framer` since creation (not cleared by :meth:`Framer.reset`)."""

    frames: int
    dropped_bytes: int
    bad_checksums: int
    bad_lengths: int


class Framer:
    """Finds complete frames of one protocol in a byte stream.

    ``protocol`` is one of :data:`PROTOCOLS`. ``max_frame`` is the largest accepted frame in
    bytes, prefix/header included (default: ARCOS 258, Simple Message 4100, ros4mat
    27 + 16 MiB, SCIP 65536). Bytes that cannot start a valid frame are dropped one at a time
    (SCIP: line by line, :mod:`robocli.protocols.scip2.framing`) and counted in :attr:`stats`.
    Not thread-safe: use one framer per stream.
    """

    def __init__(self, protocol: str, max_frame: int | None = None) -> None:
        if protocol not in _PROTO_IDS:
            raise ValueError(f"unknown protocol {protocol!r}; expected one of {PROTOCOLS}")
        if max_frame is not None and max_frame <= 0:
            raise ValueError("max_frame must be positive")
        ptr = lib.rc_framer_new(_PROTO_IDS[protocol], max_frame or 0)
        if ptr == ffi.NULL:
            raise ValueError(f"max_frame {max_frame} is too small for {protocol}")
        self._f = ffi.gc(ptr, lib.rc_framer_free)
        self._frame = ffi.new("const unsigned char **")
        self._len = ffi.new("size_t *")
        self._stats = ffi.new("rc_framer_stats *")
        self.protocol = protocol

    def feed(self, data: Buffer) -> list[bytes]:
        """Append ``data`` to the stream and return every frame now complete, in order."""
        f = self._f
        if len(data):
            # bytes go to C as they are (cffi passes their buffer); other buffers get a view
            buf = data if type(data) is bytes else _bytes_view(data)
            if lib.rc_framer_feed(f, buf, len(buf)) != 0:
                raise MemoryError("framer buffer could not grow")
        # the loop of frames() inlined: this runs once per read on every link
        out: list[bytes] = []
        fp, lp, nxt, buffer = self._frame, self._len, lib.rc_framer_next, ffi.buffer
        while nxt(f, fp, lp):
            out.append(buffer(fp[0], lp[0])[:])
        return out

    def frames(self) -> Iterator[bytes]:
        """Take the complete frames already buffered, without feeding."""
        f, fp, lp = self._f, self._frame, self._len
        nxt, buffer = lib.rc_framer_next, ffi.buffer
        while nxt(f, fp, lp):
            yield buffer(fp[0], lp[0])[:]

    @property
    def stats(self) -> FramerStats:
        lib.rc_framer_get_stats(self._f, self._stats)
        s = self._stats
        return FramerStats(
            int(s.frames), int(s.dropped_bytes), int(s.bad_checksums), int(s.bad_lengths)
        )

    @property
    def pending(self) -> int:
        """Bytes buffered but not yet framed (a partial frame, or bytes not yet judged)."""
        return int(lib.rc_framer_pending(self._f))

    def reset(self) -> None:
        """Forget the buffered bytes (after a reconnect); the counters are kept."""
        lib.rc_framer_reset(self._f)

    def count(self, data: Buffer, chunk: int = 0) -> int:
        """Feed ``data`` in ``chunk``-byte pieces (0: at once), drop the frames, count them.

        For benchmarks: no Python object is created per frame.
        """
        if chunk < 0:
            raise ValueError("chunk must be >= 0")
        buf = _bytes_view(data)
        return int(lib.rc_framer_count(self._f, buf, len(buf), chunk))
