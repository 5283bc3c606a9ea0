"""Typed wrapper of the C core (``robocli._core``, built by cffi from ``csrc/``).

Only this package and ``robocli.protocols.scip2.fast`` import the extension. It offers, one
module per job:

* :mod:`.framing` -- :func:`arcos_checksum` and :class:`Framer`: find frames of ARCOS,
  Simple Message (little/big-endian length prefix), ros4mat and SCIP 2.0 in any chunking of a
  byte stream, resynchronising one byte at a time after garbage and counting what was dropped;
* :mod:`.ring` -- :class:`Ring`: one writer, many readers ring of timestamped fixed-size
  records, each reader with its own cursor and limit;
* :mod:`.align` -- :func:`align_nearest` / :func:`align_linear`: map sorted sample times of K
  streams onto one sorted reference timeline;
* :mod:`.peers` -- :class:`PingPong` / :func:`pingpong_floor`: the machine's loopback TCP
  round-trip floor, measured in C, each end optionally pinned to a CPU; and
  :class:`Responder`, a minimal ARCOS server in C answering frames from a canned table.

The C calls release the GIL. :class:`Framer` objects are not thread-safe (use one per
stream); :class:`Ring` is thread-safe (the C ring locks itself). NumPy is imported only by the
ring, alignment and floor functions, so a client that only frames bytes does not load it.
"""

from robocli.core.align import align_linear, align_nearest
from robocli.core.framing import PROTOCOLS, Framer, FramerStats, arcos_checksum
from robocli.core.peers import PingPong, Responder, ResponderStats, pin_supported, pingpong_floor
from robocli.core.ring import Ring

__all__ = [
    "PROTOCOLS",
    "Framer",
    "FramerStats",
    "Ring",
    "align_linear",
    "align_nearest",
    "arcos_checksum",
    "pin_supported",
    "pingpong_floor",
    "PingPong",
    "Responder",
    "ResponderStats",
]
