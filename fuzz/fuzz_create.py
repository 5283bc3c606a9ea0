"""Fuzz harness of the iRobot Create 2 Open Interface (``create-oi``).

An input is a byte stream as the Create simulator receives it from a toolkit, cut into
chunks (sizes from its first bytes, as the framer harnesses do):

* the :class:`~robocli.protocols.create_oi.CommandFramer` must give, after every chunk, the
  commands, dropped bytes and pending bytes of an oracle written apart from it (command
  lengths typed from the specification's table here, not taken from the package);
* every command it frames must parse, and build back to the same bytes;
* each command goes to a real :class:`~robocli.sim.create.session.CreateController` (an
  empty world, in-process, stepped between chunks): it must not raise, and every reply is
  exactly the packets' size;
* the same bytes, as a client's :class:`~robocli.protocols.create_oi.StreamFramer` reads
  the robot's output, must give only frames whose header, length and checksum hold (each
  then decodes or raises a :class:`robocli.errors.RobocliError`), with every input byte
  either framed, dropped or pending; read as a stream frame or sensor data, they must decode
  or raise a :class:`robocli.errors.RobocliError`.

Any other exception, or a broken invariant (an ``AssertionError``), is a finding.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

from robocli.errors import RobocliError
from robocli.protocols import create_oi as oi
from robocli.sim.create.model import CreateBody
from robocli.sim.create.session import CreateController, CreateSession
from robocli.sim.world import World

SPEC = Path(__file__).resolve().parent.parent / "specs" / "create_oi.jsonl"

#: opcode -> whole command length, for the commands whose length is fixed (the
#: specification's command table); 140 (song), 148 and 149 (id lists) are variable.
FIXED = {7: 1, 128: 1, 129: 2, 130: 1, 131: 1, 132: 1, 133: 1, 134: 1, 135: 1, 136: 1,
         137: 5, 138: 2, 139: 4, 141: 2, 142: 2, 143: 1, 144: 4, 145: 5, 146: 5, 150: 2,
         162: 3, 163: 5, 164: 5, 165: 2, 167: 16, 168: 4, 173: 1}  # fmt: skip


def oracle(stream: bytes) -> tuple[list[bytes], int, int]:
    """(commands, dropped bytes, pending bytes) of a whole ``stream``."""
    out: list[bytes] = []
    i = dropped = 0
    while i < len(stream):
        op, rest = stream[i], len(stream) - i
        if op in FIXED:
            n: int | None = FIXED[op]
        elif op in (148, 149):
            n = 2 + stream[i + 1] if rest >= 2 else None
        elif op == 140:
            number = stream[i + 1] if rest >= 2 else 0
            length = stream[i + 2] if rest >= 3 else 1
            n = 3 + 2 * length if rest >= 3 else None
            if number > 4 or not 1 <= length <= 16:
                dropped, i = dropped + 1, i + 1
                continue
        else:
            dropped, i = dropped + 1, i + 1
            continue
        if n is None or n > rest:
            break
        out.append(stream[i : i + n])
        i += n
    return out, dropped, len(stream) - i


class _Link:
    """What a session needs of its link here: nothing is sent through it."""

    def send(self, data: bytes) -> bool:  # pragma: no cover - the ticker is not running
        return True


def _chunks(data: bytes) -> list[bytes]:
    if len(data) < 2:
        return [data]
    step = data[1] % 17 or len(data) or 1
    stream = data[2:]
    return [stream[i : i + step] for i in range(0, len(stream), step)]


def fuzz_create(data: bytes) -> None:
    """One input (see the module docstring)."""
    framer = oi.CommandFramer()
    ctl = CreateController(CreateBody(World.empty(), (0.0, 0.0, 0.0)))
    session = CreateSession(ctl, _Link())  # type: ignore[arg-type]
    fed = b""
    got: list[bytes] = []
    for chunk in _chunks(data):
        fed += chunk
        commands = framer.feed(chunk)
        got += commands
        want, dropped, pending = oracle(fed)
        assert got == want, ([c.hex() for c in got], [c.hex() for c in want])
        assert framer.stats.dropped_bytes == dropped and framer.pending == pending
        for command in commands:
            op, params = oi.parse_command(command)
            assert oi.build_command(op, **params) == command, command.hex()
            reply = session.on_frame(command, 0.0)
            if reply is not None and op in (oi.Op.SENSORS, oi.Op.QUERY_LIST):
                ids = [params["packet"]] if op == oi.Op.SENSORS else params["packets"]
                assert len(reply) == sum(oi.packet_size(i) for i in ids), command.hex()
        with ctl.lock:
            ctl.tick(0.015)
    _client_side(data)
    for decode in (oi.parse_stream, lambda b: oi.decode_packets(b[:1], b[1:])):
        try:
            decode(data)
        except RobocliError:
            pass


def _client_side(data: bytes) -> None:
    framer = oi.StreamFramer()
    framed = 0
    for chunk in _chunks(data):
        for frame in framer.feed(chunk):
            framed += len(frame)
            assert frame[0] == oi.STREAM_HEADER and frame[1] + 3 == len(frame), frame.hex()
            assert sum(frame) & 0xFF == 0, frame.hex()
            try:
                oi.parse_stream(frame)
            except RobocliError:
                pass
        assert framer.pending <= 258
    total = sum(map(len, _chunks(data)))
    assert framed + framer.stats.dropped_bytes + framer.pending == total


def seed_inputs() -> list[bytes]:
    """The golden vectors (commands and stream frames) whole, byte by byte, run together
    behind garbage, and pycreate2's opening (start, safe, songs, drive, group 100)."""
    lines = SPEC.read_text().splitlines()[1:]
    frames = [bytes.fromhex(json.loads(line)["hex"]) for line in lines if line]
    opening = bytes([128, 131, 140, 0, 1, 70, 0, 141, 0, 145, 0, 200, 0, 200, 142, 100])
    out = [b"\x00\x00" + f for f in frames] + [b"\x00\x01" + f for f in frames]
    return [*out, b"\x00\x05\x00\xff" + b"".join(frames), b"\x00\x00" + opening]


TARGETS: dict[str, tuple[Callable[[bytes], None], tuple[str, ...]]] = {
    "create-oi": (fuzz_create, ()),
}
