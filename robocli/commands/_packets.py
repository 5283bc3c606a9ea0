"""``robocli dump pioneer``'s view of packets: names by handshake phase, short text lines
or JSON Lines, in time order, optionally recorded to a ``.jsonl`` capture."""

from __future__ import annotations

import heapq
import itertools
import json
import sys
from typing import Any

from robocli.commands._common import rounded
from robocli.devices.pioneer.simulated import SIMULATOR_NAMES
from robocli.errors import ProtocolError
from robocli.io.capture import CaptureWriter
from robocli.protocols import arcos
from robocli.protocols.arcos import Command, PacketType

#: Longest text line of a packet unless ``-v`` (the rest is cut with an ellipsis).
LINE_MAX = 160
#: Command argument markers: int >= 0, int < 0, string.
_ARG_MARKS = (0x3B, 0x1B)
_STRING_MARK = 0x2B
_ARROWS = {"tx": "->", "rx": "<-"}
#: What commands 35-38 mean to a simulator (MobileSim/AMRISim's SRISim laser compatibility,
#: shared/protocols/arcos_sim_laser.md section 1); a real robot reads them as ADSEL, ...
_SIM_COMMANDS = {
    35: "OLD_LRF_ENABLE", 36: "OLD_LRF_CFG_START", 37: "OLD_LRF_CFG_END", 38: "OLD_LRF_CFG_INC",
}  # fmt: skip


def guess_direction(payload: bytes, in_session: bool) -> str:
    """Direction of a packet of a raw capture, from its shape: a client command is a type
    byte alone or followed by one argument (int: 0x3B/0x1B + 2 bytes; string: 0x2B + length
    + bytes); the robot's packets (SYNC2 reply, SIP, CONFIG...) are anything else."""
    n = len(payload)
    if n == 1:
        return "tx" if in_session or payload[0] > 2 else "?"
    if n == 4 and payload[1] in _ARG_MARKS:
        return "tx"
    if n >= 3 and payload[1] == _STRING_MARK and payload[2] == n - 3:
        return "tx"
    return "rx"


class PacketView:
    """Names and renders packets one at a time; :meth:`add` takes them in any order and
    :meth:`flush` prints those older than a reordering window, in time order."""

    def __init__(
        self,
        *,
        json_out: bool = False,
        hex_out: bool = False,
        full: bool = False,
        count: int = 0,
        writer: CaptureWriter | None = None,
    ) -> None:
        self.json_out, self.hex_out, self.full, self.count = json_out, hex_out, full, count
        self.writer = writer
        self.printed = 0
        self.in_session = False
        self.simulator = False  #: the robot said it is a simulator (name, CONFIG serial)
        self._heap: list[tuple[float, int, str, bytes]] = []
        self._seq = itertools.count()

    @property
    def done(self) -> bool:
        """True once ``count`` packets were printed (never with ``count`` 0)."""
        return bool(self.count) and self.printed >= self.count

    def add(self, direction: str, payload: bytes, t: float) -> None:
        """Queue one packet seen at ``t`` (seconds since the start)."""
        heapq.heappush(self._heap, (t, next(self._seq), direction, payload))

    def flush(self, before: float = float("inf")) -> None:
        """Print queued packets seen before ``before``, oldest first."""
        heap = self._heap
        while heap and heap[0][0] < before and not self.done:
            t, _, direction, payload = heapq.heappop(heap)
            self.show(direction, payload, t)

    def show(self, direction: str, payload: bytes, t: float | None) -> None:
        """Print one packet now (``direction``: "tx", "rx" or "?" for a raw capture)."""
        if direction == "?":
            direction = guess_direction(payload, self.in_session)
        name, fields = self.describe(direction, payload)
        if self.writer is not None:
            self.writer.write(t or 0.0, direction, arcos.frame(payload))
        if self.json_out:
            record = {"t": t, "dir": direction, "type": payload[0], "name": name, "fields": fields}
            sys.stdout.write(json.dumps(rounded(record), default=str) + "\n")
        else:
            sys.stdout.write(self._text(direction, name, fields, t) + "\n")
            if self.hex_out:
                sys.stdout.write(f"{'':13}{arcos.frame(payload).hex(' ')}\n")
        sys.stdout.flush()
        self.printed += 1

    def describe(self, direction: str, payload: bytes) -> tuple[str, dict[str, Any]]:
        """Name (by handshake phase) and decoded fields of one packet; None fields dropped."""
        ptype = payload[0]
        handshake = not self.in_session and ptype <= 2
        if handshake and direction != "tx":
            # the robot's SYNC replies: SYNC2's carries its identity (not a CLOSE)
            if len(payload) > 1 and ptype == 2:
                try:
                    name, kind, subtype = arcos.parse_sync_reply(payload[1:])
                except ProtocolError as exc:
                    return "SYNC2-reply", {"raw": payload[1:].hex(), "error": str(exc)}
                self.simulator = name in SIMULATOR_NAMES
                return "SYNC2-reply", {"name": name, "type": kind, "subtype": subtype}
            return (f"SYNC{ptype}-reply" if direction == "rx" else f"SYNC{ptype}"), {}
        from_client = direction == "tx"
        name, fields = arcos.describe(payload, from_client=from_client, in_session=True)
        if from_client and self.simulator and ptype in _SIM_COMMANDS:
            name = f"{name}|sim:{_SIM_COMMANDS[ptype]}"  # as the traces' decoder names them
        elif not from_client and ptype == PacketType.CONFIG and fields.get("serial") == "SIM":
            self.simulator = True
        if handshake and len(payload) == 1:
            name = f"SYNC{ptype}"
        if (from_client and ptype == Command.OPEN and len(payload) > 1) or (
            not from_client and ptype & 0xF0 == 0x30
        ):
            self.in_session = True  # OPEN with its argument, or a SIP: the session started
        return name, {k: v for k, v in fields.items() if v is not None}

    def _text(self, direction: str, name: str, fields: dict[str, Any], t: float | None) -> str:
        stamp = f"{t:9.3f} " if t is not None else ""
        text = " ".join(f"{k}={_short(v, self.full)}" for k, v in fields.items())
        line = f"{stamp}{_ARROWS.get(direction, '  ')} {name:<12} {text}".rstrip()
        if not self.full and len(line) > LINE_MAX:
            mark = ellipsis()
            line = line[: LINE_MAX - len(mark)] + mark
        return line


def ellipsis() -> str:
    """``…`` where standard output can encode it, else ``...`` (a latin-1 or ASCII
    terminal, ``PYTHONIOENCODING=ascii``)."""
    try:
        "\u2026".encode(getattr(sys.stdout, "encoding", None) or "ascii")
    except (UnicodeEncodeError, LookupError):
        return "..."
    return "\u2026"


def _short(value: Any, full: bool) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, list) and value and isinstance(value[0], (tuple, dict)):
        # sonar (number, range) pairs, laser readings {range, reflectance...}
        if full:
            return "[" + ",".join(_short(v, full) for v in value) + "]"
        ranges = [v["range"] if isinstance(v, dict) else v[-1] for v in value]
        return f"{len(value)}(min {min(ranges)})"  # how many, the nearest
    if isinstance(value, tuple):
        return ":".join(map(str, value))
    if isinstance(value, list) and len(value) > 8 and not full:
        return f"{len(value)}(min {min(value)})"  # laser ranges: how many, the nearest
    if isinstance(value, dict):
        return (
            "{"
            + ",".join(f"{k}={_short(v, full)}" for k, v in value.items() if v is not None)
            + "}"
        )
    return str(value)
