"""Pure-Python reference implementations of the C core, for differential tests.

Written for clarity, not speed: checksum, the three binary framers (same resynchronisation
rule: drop one byte; SCIP 2.0's line framer is the package's own pure-Python
``robocli.protocols.scip2.ReplyFramer``), the multi-reader ring and timestamp alignment
(nearest and linear). Also the one loader of the golden vectors in ``specs/`` that every
Python test (and the fuzzers) use.
"""

from __future__ import annotations

import json
import random
import struct
from bisect import bisect_left, bisect_right
from collections import deque
from pathlib import Path
from typing import Any, Protocol

from robocli.core import FramerStats
from robocli.protocols.scip2.framing import ReplyFramer

SPECS_DIR = Path(__file__).resolve().parent.parent / "specs"
SPEC_NAMES = ("arcos", "ros4mat", "scip2", "simple_message")
FRAMER_KINDS = ("arcos", "sm-le", "sm-be", "ros4mat", "scip2")


class SpecError(ValueError):
    """A golden-vector file that cannot prove anything: missing, empty, miscounted."""


def load_spec(name: str, folder: Path = SPECS_DIR) -> dict[str, Any]:
    """Parse ``folder/name.json`` and check it: a top-level ``count`` equal to the number of
    ``vectors`` (at least one), each with a ``name``, a known ``framer`` and a non-empty
    ``hex``, each on its own line (the C suite reads them line by line and checks the same
    count). Raises :class:`SpecError` otherwise."""
    path = Path(folder) / f"{name}.json"
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SpecError(f"{path}: cannot read golden vectors: {exc}") from exc
    spec = json.loads(text)
    vectors = spec.get("vectors")
    count = spec.get("count")
    if not isinstance(vectors, list) or not vectors:
        raise SpecError(f"{path}: no golden vectors")
    if not isinstance(count, int) or count != len(vectors):
        raise SpecError(f"{path}: declares count {count!r}, holds {len(vectors)} vectors")
    for vec in vectors:
        if vec.get("framer") not in FRAMER_KINDS or not vec.get("name") or not vec.get("hex"):
            raise SpecError(f"{path}: malformed vector {str(vec)[:80]}")
        bytes.fromhex(vec["hex"])
    lines = [line for line in text.splitlines() if '"framer"' in line]
    if len(lines) != count:
        raise SpecError(f"{path}: {count} vectors on {len(lines)} lines (one per line)")
    return dict(spec)


def load_specs(folder: Path = SPECS_DIR) -> dict[str, dict[str, Any]]:
    """Every spec file of ``folder`` (all of :data:`SPEC_NAMES` must be there), checked by
    :func:`load_spec`. Raises :class:`SpecError` on an empty or incomplete folder."""
    found = sorted(p.stem for p in Path(folder).glob("*.json"))
    missing = [n for n in SPEC_NAMES if n not in found]
    if not found or missing:
        raise SpecError(f"{folder}: golden-vector files missing: {missing or list(SPEC_NAMES)}")
    return {name: load_spec(name, folder) for name in found}


def golden_frames(folder: Path = SPECS_DIR) -> list[tuple[str, str, bytes]]:
    """(framer kind, vector name, frame bytes) of every golden vector of ``folder``."""
    return [
        (v["framer"], v["name"], bytes.fromhex(v["hex"]))
        for spec in load_specs(folder).values()
        for v in spec["vectors"]
    ]


ARCOS_DEFAULT_MAX = 258
SM_DEFAULT_MAX = 4100
R4M_HEADER = 27
R4M_DEFAULT_MAX = 27 + 16 * 1024 * 1024
SCIP_DEFAULT_MAX = 65536


def arcos_checksum(data: bytes) -> int:
    c = 0
    i = 0
    n = len(data)
    while n - i > 1:
        c = (c + (data[i] << 8 | data[i + 1])) & 0xFFFF
        i += 2
    if n - i == 1:
        c ^= data[i]
    return c


def arcos_packet(ptype: int, data: bytes = b"") -> bytes:
    """A whole ARCOS packet of type ``ptype`` carrying ``data``."""
    body = bytes([ptype]) + data
    ck = arcos_checksum(body)
    return b"\xfa\xfb" + bytes([len(body) + 2]) + body + bytes([ck >> 8, ck & 0xFF])


class RefFramer:
    """Same contract as robocli.core.Framer: feed bytes, get the complete frames."""

    def __init__(self, protocol: str, max_frame: int | None = None) -> None:
        defaults = {
            "arcos": ARCOS_DEFAULT_MAX,
            "sm-le": SM_DEFAULT_MAX,
            "sm-be": SM_DEFAULT_MAX,
            "ros4mat": R4M_DEFAULT_MAX,
            "scip2": SCIP_DEFAULT_MAX,
        }
        if protocol not in defaults:
            raise ValueError(protocol)
        self.protocol = protocol
        self.max_frame = max_frame or defaults[protocol]
        self.buf = bytearray()
        self._counts = dict.fromkeys(("frames", "dropped_bytes", "bad_checksums", "bad_lengths"), 0)
        self._scip = ReplyFramer(self.max_frame) if protocol == "scip2" else None

    @property
    def stats(self) -> FramerStats:
        """The counters, as the C framer reports them."""
        if self._scip is not None:
            return FramerStats(*vars(self._scip.stats).values())
        return FramerStats(**self._counts)

    @property
    def pending(self) -> int:
        return self._scip.pending if self._scip is not None else len(self.buf)

    def reset(self) -> None:
        self.buf.clear()
        if self._scip is not None:
            self._scip.reset()

    def feed(self, data: bytes) -> list[bytes]:
        if self._scip is not None:
            frames = self._scip.feed(data)
            return frames
        self.buf += data
        out = []
        while True:
            frame = self._next()
            if frame is None:
                return out
            out.append(frame)

    def _drop(self) -> None:
        del self.buf[0]
        self._counts["dropped_bytes"] += 1

    def _emit(self, total: int) -> bytes:
        frame = bytes(self.buf[:total])
        del self.buf[:total]
        self._counts["frames"] += 1
        return frame

    def _next(self) -> bytes | None:
        if self.protocol == "arcos":
            return self._next_arcos()
        if self.protocol == "ros4mat":
            return self._next_r4m()
        return self._next_sm()

    def _next_arcos(self) -> bytes | None:
        b = self.buf
        while True:
            if not b:
                return None
            if b[0] != 0xFA:
                self._drop()
                continue
            if len(b) < 2:
                return None
            if b[1] != 0xFB:
                self._drop()
                continue
            if len(b) < 3:
                return None
            count = b[2]
            total = count + 3
            if count < 3 or total > self.max_frame:
                self._counts["bad_lengths"] += 1
                self._drop()
                continue
            if len(b) < total:
                return None
            if arcos_checksum(bytes(b[3 : total - 2])) != (b[total - 2] << 8 | b[total - 1]):
                self._counts["bad_checksums"] += 1
                self._drop()
                continue
            return self._emit(total)

    def _next_sm(self) -> bytes | None:
        b = self.buf
        fmt = "<I" if self.protocol == "sm-le" else ">I"
        while True:
            if len(b) < 4:
                return None
            (length,) = struct.unpack_from(fmt, b)
            if not 12 <= length <= self.max_frame - 4:
                self._counts["bad_lengths"] += 1
                self._drop()
                continue
            if len(b) < 4 + length:
                return None
            return self._emit(4 + length)

    def _next_r4m(self) -> bytes | None:
        b = self.buf
        while True:
            if len(b) < R4M_HEADER:
                return None
            _type, error, _cid, size, usize, csize, ctype, _ts = struct.unpack_from("<bbIIIIbd", b)
            body = csize if (error != 0 or size != 0) else 0
            mtype = b[0]
            ok = (
                ctype in (0, 1)
                and error in (0, 1)
                and mtype != 0
                and (mtype >> 4) in (0, 1, 2, 8, 9)
            )
            if ok and ctype == 0 and error == 0 and size != 0 and csize != usize:
                ok = False
            if ok and R4M_HEADER + body > self.max_frame:
                ok = False
            if not ok:
                self._counts["bad_lengths"] += 1
                self._drop()
                continue
            if len(b) < R4M_HEADER + body:
                return None
            return self._emit(R4M_HEADER + body)


def sm_frame(body: bytes, little: bool = True, msg_type: int = 10) -> bytes:
    """A Simple Message frame: prefix + 12-byte header + body."""
    e = "<" if little else ">"
    header = struct.pack(e + "iii", msg_type, 1, 0) + body
    return struct.pack(e + "i", len(header)) + header


def r4m_frame(mtype: int, body: bytes = b"", size: int | None = None, error: bool = False) -> bytes:
    """A ros4mat frame (uncompressed); ``error`` makes ``body`` the error text."""
    n = (1 if body else 0) if size is None else size
    header = struct.pack(
        "<bbIIIIbd",
        mtype,
        1 if error else 0,
        7,
        0 if error else n,
        0 if error else len(body),
        len(body),
        0,
        0.0,
    )
    return header + body


class RefRing:
    """Same semantics as robocli.core.Ring, with an explicit queue per reader."""

    def __init__(self, record_size: int, capacity: int) -> None:
        self.record_size = record_size
        self.capacity = capacity
        self.pushed = 0
        self.readers: dict[int, tuple[deque[tuple[float, bytes]], list[int]]] = {}

    def push(self, t: float, record: bytes) -> None:
        assert len(record) == self.record_size
        self.pushed += 1
        for q, lost in self.readers.values():
            if len(q) == q.maxlen:
                lost[0] += 1
            q.append((t, bytes(record)))

    def push_many(self, t: list[float], records: bytes) -> None:
        rs = self.record_size
        for i, ti in enumerate(t):
            self.push(ti, records[i * rs : (i + 1) * rs])

    def add_reader(self, limit: int | None = None) -> int:
        rid = 0
        while rid in self.readers:
            rid += 1
        lim = self.capacity if not limit or limit > self.capacity else limit
        self.readers[rid] = (deque(maxlen=lim), [0])
        return rid

    def remove_reader(self, reader: int) -> None:
        del self.readers[reader]

    def available(self, reader: int) -> int:
        return len(self.readers[reader][0])

    def lost(self, reader: int) -> int:
        return self.readers[reader][1][0]

    def read(self, reader: int, max_records: int | None = None) -> list[tuple[float, bytes]]:
        q = self.readers[reader][0]
        n = len(q) if max_records is None else min(len(q), max_records)
        return [q.popleft() for _ in range(n)]


def align_nearest(ts: list[float], ref: list[float], tol: float) -> list[int]:
    out = []
    n = len(ts)
    for x in ref:
        k = bisect_right(ts, x)  # samples <= x
        best = -1
        if k > 0:
            d0 = x - ts[k - 1]
            left = bisect_left(ts, ts[k - 1])  # earliest of equal samples
            if k < n:
                d1 = ts[k] - x
                if d0 <= d1:
                    best = left if d0 <= tol else -1
                else:
                    best = k if d1 <= tol else -1
            else:
                best = left if d0 <= tol else -1
        elif n > 0:
            best = 0 if ts[0] - x <= tol else -1
        out.append(best)
    return out


def align_linear(ts: list[float], ref: list[float]) -> tuple[list[int], list[float]]:
    idx: list[int] = []
    w: list[float] = []
    n = len(ts)
    for x in ref:
        k = bisect_right(ts, x)
        if k == 0 or n == 0 or x > ts[-1]:
            idx.append(-1)
            w.append(0.0)
        elif k == n:
            if n == 1:
                idx.append(0)
                w.append(0.0)
            else:
                idx.append(n - 2)
                w.append(1.0)
        else:
            idx.append(k - 1)
            w.append((x - ts[k - 1]) / (ts[k] - ts[k - 1]))
    return idx, w


def with_garbage(
    frames: list[bytes], rng: random.Random, byte_range: tuple[int, int], longest: int
) -> tuple[bytes, int]:
    """``frames`` each preceded by 0 to ``longest - 1`` random bytes drawn from
    ``range(*byte_range)``: the stream, and how many garbage bytes it holds."""
    pieces, garbage = [], 0
    for frame in frames:
        junk = bytes(rng.randrange(*byte_range) for _ in range(rng.randrange(0, longest)))
        garbage += len(junk)
        pieces += [junk, frame]
    return b"".join(pieces), garbage


class Feeds(Protocol):
    def feed(self, data: bytes) -> list[bytes]: ...


def fed_in_chunks(framer: Feeds, stream: bytes, size: int) -> list[bytes]:
    """The frames ``framer`` returns when fed ``stream`` ``size`` bytes at a time."""
    out: list[bytes] = []
    for i in range(0, len(stream), size):
        out += framer.feed(stream[i : i + size])
    return out
