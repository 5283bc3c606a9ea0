"""Fuzz harnesses of the C framers (``robocli.core.Framer``, through the cffi module).

Each input is split into chunks (sizes taken from its first bytes) and fed to the C framer
and to the pure-Python reference framer of ``tests/reference.py``. They must return the same
frames, the same counters and the same pending byte count after every chunk, and every frame
must satisfy the protocol's own framing rule. A difference, or any exception, is a finding.
"""

from __future__ import annotations

import re
from collections.abc import Callable

import reference

from robocli.core import Framer
from robocli.protocols import scip2

#: harness name -> (framer protocol, golden-vector kinds seeding it)
TARGETS = {
    "framer-arcos": ("arcos", ("arcos",)),
    "framer-sm-le": ("sm-le", ("sm-le",)),
    "framer-sm-be": ("sm-be", ("sm-be",)),
    "framer-ros4mat": ("ros4mat", ("ros4mat",)),
    "framer-scip2": ("scip2", ("scip2",)),
    "framer-scip2-requests": ("scip2-requests", ("scip2",)),
}


def _chunks(data: bytes) -> tuple[int | None, list[bytes]]:
    """(max_frame or None, the stream in chunks) from one fuzz input."""
    if len(data) < 2:
        return None, [data]
    head, stream = data[:2], data[2:]
    max_frame = None if head[0] & 0x80 == 0 else 32 + head[0] * 4  # small limits sometimes
    step = head[1] % 17 or len(stream) or 1
    return max_frame, [stream[i : i + step] for i in range(0, len(stream), step)]


def check_frame(protocol: str, frame: bytes) -> None:
    """The protocol's framing rule, checked independently of both framers."""
    if protocol == "arcos":
        assert frame[:2] == b"\xfa\xfb" and frame[2] + 3 == len(frame), frame.hex()
        body = frame[3:-2]
        assert reference.arcos_checksum(body) == int.from_bytes(frame[-2:], "big"), frame.hex()
    elif protocol == "scip2":  # echo, a 1-char or summed 3-char status, ..., empty line
        lines = frame.replace(b"\r\n", b"\n").split(b"\n")
        assert len(lines) >= 4 and lines[-2:] == [b"", b""] and b"" not in lines[:-2], frame
        assert all(0x20 <= c <= 0x7E for c in b"".join(lines)), frame
        status = lines[1]
        assert len(status) == 1 or (len(status) == 3 and status[2] == scip2.checksum(status[:2]))
    elif protocol in ("sm-le", "sm-be"):
        length = int.from_bytes(frame[:4], "little" if protocol == "sm-le" else "big", signed=True)
        assert length + 4 == len(frame), frame.hex()
    else:
        assert len(frame) >= reference.R4M_HEADER, frame.hex()


def fuzz_framer(protocol: str, data: bytes) -> None:
    """One input: C framer == reference framer, chunk by chunk."""
    max_frame, chunks = _chunks(data)
    try:
        c_framer = Framer(protocol, max_frame=max_frame)
    except ValueError:  # a limit below the protocol's minimum is refused, as documented
        return
    ref = reference.RefFramer(protocol, max_frame=max_frame)
    for chunk in chunks:
        got, want = c_framer.feed(chunk), ref.feed(chunk)
        assert got == want, (protocol, [f.hex() for f in got], [f.hex() for f in want])
        assert c_framer.stats == ref.stats, (protocol, c_framer.stats, ref.stats)
        assert c_framer.pending == ref.pending, (protocol, c_framer.pending, ref.pending)
        for frame in got:
            check_frame(protocol, frame)


def seed_inputs(frames: list[bytes]) -> list[bytes]:
    """Golden frames as inputs: whole, byte by byte, and all of them behind garbage."""
    whole = [b"\x00\x00" + f for f in frames]
    bytewise = [b"\x00\x01" + f for f in frames]
    return [*whole, *bytewise, b"\x00\x05\x00\xfa\xff" + b"".join(frames)]


def _reference_requests(stream: bytes, max_line: int) -> tuple[list[bytes], int, int, int]:
    """What a request framer must make of a whole ``stream`` (an oracle written apart from
    :class:`RequestFramer`): (lines, dropped bytes, over-long lines, pending bytes). A line
    ends at LF, CR or CR LF; empty lines are skipped; a line longer than ``max_line`` is
    dropped whole, even while still unterminated."""
    parts = re.split(rb"\r\n|\r|\n", stream)
    done, tail = parts[:-1], parts[-1]
    lines = [p for p in done if 0 < len(p) <= max_line]
    long = [p for p in done if len(p) > max_line]
    dropped = sum(len(p) for p in long)
    if len(tail) > max_line:
        long.append(tail)
        dropped += len(tail)
    return lines, dropped, len(long), len(tail) if len(tail) <= max_line else 0


def fuzz_requests(data: bytes) -> None:
    """One input: the simulator's :class:`RequestFramer`, fed in chunks, gives the lines,
    counters and pending bytes of the oracle after every chunk; every line is one the
    simulator can take (no terminator, within the limit), and its session's parser either
    reads it or refuses it with a robocli error."""
    from robocli.errors import RobocliError
    from robocli.protocols.scip2.framing import MAX_REQUEST, RequestFramer

    max_frame, chunks = _chunks(data)
    limit = MAX_REQUEST if max_frame is None else max_frame % 97 + 1
    framer = RequestFramer(limit)
    fed = b""
    got: list[bytes] = []
    for chunk in chunks:
        fed += chunk
        lines = framer.feed(chunk)
        got += lines
        want, dropped, long, pending = _reference_requests(fed, limit)
        assert got == want, (got, want)
        stats = framer.stats
        assert (stats.frames, stats.dropped_bytes, stats.bad_lengths) == (
            len(want), dropped, long,
        ), (stats, dropped, long)  # fmt: skip
        assert framer.pending == pending, (framer.pending, pending)
        for line in lines:
            assert 0 < len(line) <= limit and b"\r" not in line and b"\n" not in line, line
            try:
                scip2.parse_request(line)
            except RobocliError:
                pass


def request_seeds(blocks: list[bytes]) -> list[bytes]:
    """Request lines (the echo lines of the golden reply blocks, and every command the
    simulator knows) with each terminator, whole, byte by byte and run together."""
    lines = {b.split(b"\n", 1)[0] for b in blocks}
    lines |= {b"QT", b"BM", b"RS", b"RT", b"VV", b"PP", b"II", b"SCIP2.0", b"TM0", b"TM1",
              b"TM2", b"GD0000108001", b"MD0044072501000", b"ME0000108001101;tag"}  # fmt: skip
    out = []
    for i, line in enumerate(sorted(lines)):
        end = (b"\n", b"\r", b"\r\n")[i % 3]
        out += [b"\x00\x00" + line + end, b"\x00\x01" + line + end]
    return [*out, b"\x00\x05" + b"\n".join(sorted(lines)) + b"\r\n\r\n", b"\x80\x03" + b"X" * 300]


def target(name: str) -> tuple[Callable[[bytes], None], tuple[str, ...]]:
    """(one-input function, seed kinds) of a harness name."""
    protocol, kinds = TARGETS[name]
    if protocol == "scip2-requests":
        return fuzz_requests, kinds

    def one_input(data: bytes) -> None:
        fuzz_framer(protocol, data)

    return one_input, kinds
