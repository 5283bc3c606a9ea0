"""The views of ``robocli dump pioneer`` and ``dump arm``: packets named and decoded (ARCOS
by handshake phase, Simple Message by type and reply code), as short text lines or JSON
Lines, in time order, optionally recorded to a ``.jsonl`` capture."""

from __future__ import annotations

import heapq
import itertools
import json
import sys
from typing import TYPE_CHECKING, Any

from robocli.commands._common import rounded
from robocli.commands._options import WIRE_DIR
from robocli.devices.pioneer.simulated import SIMULATOR_NAMES
from robocli.errors import ProtocolError
from robocli.io.capture import CaptureWriter
from robocli.protocols import arcos
from robocli.protocols.arcos import Command, PacketType

if TYPE_CHECKING:
    from robocli.protocols import simple_message as sm

#: Longest text line of a packet unless ``-v`` (the rest is cut with an ellipsis).
LINE_MAX = 160
#: Command argument markers: int >= 0, int < 0, string.
_ARG_MARKS = (0x3B, 0x1B)
_STRING_MARK = 0x2B
_ARROWS = {"tx": "->", "rx": "<-"}
#: What commands 35-38 mean to a simulator (MobileSim/AMRISim's SRISim laser compatibility,
#: docs/protocols/arcos-sim.md section 1); a real robot reads them as ADSEL, ...
_SIM_COMMANDS = {
    35: "OLD_LRF_ENABLE", 36: "OLD_LRF_CFG_START", 37: "OLD_LRF_CFG_END", 38: "OLD_LRF_CFG_INC",
}  # fmt: skip
#: Simple Message trajectory sequence numbers with a meaning of their own.
_SEQ = {-1: "start", -2: "stream", -3: "end", -4: "STOP"}
#: Short names of Simple Message fields in text lines (JSON keeps the protocol's names).
_SHORT = {"drives_powered": "powered", "e_stopped": "estop", "error_code": "code",
          "in_error": "error", "in_motion": "moving", "motion_possible": "possible",
          "valid_fields": "valid", "sequence": "seq", "robot_id": "robot"}  # fmt: skip
_VALID_BITS = {"time": 1, "positions": 2, "velocities": 4, "accelerations": 8}


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
        #: Unix time (s) of ``t`` 0, when known: JSON gives ``t`` on it (None otherwise)
        #: and the seconds since the start as ``t_rel``
        self.epoch: float | None = None
        self.printed = 0
        self.in_session = False
        self.simulator = False  #: the robot said it is a simulator (name, CONFIG serial)
        self._heap: list[tuple[float, int, str, bytes]] = []
        self._seq = itertools.count()

    def start(self, unix_time: float | None) -> None:
        """Say when ``t`` 0 is (Unix time, s), once; a capture being written says it too."""
        if self.epoch is None and unix_time is not None:
            self.epoch = unix_time
            if self.writer is not None:
                self.writer.begin(unix_time)

    def stamp(self, t: float | None) -> dict[str, float | None]:
        """``t`` (Unix time, when known) and ``t_rel`` (seconds since the start) of JSON."""
        return {"t": None if t is None or self.epoch is None else self.epoch + t, "t_rel": t}

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
            record = {**self.stamp(t), "dir": WIRE_DIR.get(direction, direction),
                      "type": payload[0], "name": name,
                      "fields": fields}  # fmt: skip
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


# ------------------------------------------------------------------ Simple Message (dump arm)


def describe_message(frame: bytes, order: sm.ByteOrder = "<", real: sm.RealSize = 4,
                     n_joints: int = 6) -> tuple[str, dict[str, Any]]:  # fmt: skip
    """Name and decoded fields of one whole Simple Message frame (joints cut to
    ``n_joints``). A frame that does not decode is named ``undecodable`` with the reason."""
    from robocli.errors import FramingError
    from robocli.protocols import simple_message as sm
    from robocli.protocols.simple_message import CommType, MsgType, ReplyCode

    try:
        msg = sm.decode(frame, byteorder=order, real=real)
    except (FramingError, ProtocolError) as exc:
        return "undecodable", {"error": str(exc)}
    name = msg.msg_type.name if isinstance(msg.msg_type, MsgType) else f"TYPE_{msg.msg_type}"
    if msg.comm_type == CommType.SERVICE_REQUEST:
        name += " req"
    elif msg.comm_type == CommType.SERVICE_REPLY:
        code = msg.reply_code
        name += " " + (code.name if isinstance(code, ReplyCode) else f"reply {code}")
    body = msg.body
    if not isinstance(body, dict):
        return name, ({"bytes": len(body)} if isinstance(body, bytes) and body else {})
    valid = body.get("valid_fields")
    fields: dict[str, Any] = {}
    for key, value in body.items():
        if valid is not None and key in _VALID_BITS and not valid & _VALID_BITS[key]:
            continue  # JOINT_FEEDBACK / JOINT_TRAJ_PT_FULL: only the fields it says are valid
        if isinstance(value, list):
            value = value[:n_joints]
        if key == "sequence" and value in _SEQ:
            value = f"{value}({_SEQ[value]})"
        fields[key] = value
    return name, fields


class ArmPacketView(PacketView):
    """A :class:`PacketView` (its time ordering and ``--count``) that shows Simple Message
    frames of ``order`` and ``real`` size, joints cut to ``n_joints``; each queued direction
    is ``"tx:motion"``-style (direction and port)."""

    def __init__(self, order: sm.ByteOrder, real: sm.RealSize, n_joints: int,
                 **options: Any) -> None:  # fmt: skip
        super().__init__(**options)
        self.order, self.real, self.n_joints = order, real, n_joints

    def show(self, direction: str, payload: bytes, t: float | None) -> None:
        """Print one frame now (``payload``: the whole frame, ``direction``: dir:port)."""
        way, _, port = direction.partition(":")
        name, fields = describe_message(payload, self.order, self.real, self.n_joints)
        if self.writer is not None:
            self.writer.write(t or 0.0, way, payload, port or None)
        if self.json_out:
            record = {**self.stamp(t), "port": port or None, "dir": WIRE_DIR.get(way, way),
                      "name": name,
                      "fields": fields}  # fmt: skip
            if self.hex_out:
                record["hex"] = payload.hex()
            sys.stdout.write(json.dumps(rounded(record), default=str) + "\n")
        else:
            text = " ".join(f"{_SHORT.get(k, k)}={_short_sm(v)}" for k, v in fields.items())
            stamp = f"{t:9.3f} " if t is not None else ""
            line = f"{stamp}{port or '-':<6} {_ARROWS.get(way, '  ')} {name:<22} {text}"
            line = line.rstrip()
            mark = ellipsis()
            cut = line if len(line) <= LINE_MAX else line[: LINE_MAX - len(mark)] + mark
            sys.stdout.write(cut + "\n")
            if self.hex_out:
                sys.stdout.write(f"{'':13}{payload.hex(' ')}\n")
        sys.stdout.flush()
        self.printed += 1


def _short_sm(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, list):
        return "[" + ",".join(_short_sm(v) for v in value) + "]"
    return str(value)


class HubPacketView(PacketView):
    """``dump hub``'s view of ros4mat messages, live (from the proxy's threads, one at a
    time) or from a capture: named and decoded as :func:`robocli.analysis.ros4mat.describe`
    does, each printed at once (the proxy gives them in order)."""

    def show(self, direction: str, payload: bytes, t: float | None) -> None:
        """Print one whole frame now (``direction``: "tx" client to hub, "rx" back)."""
        from robocli.analysis.ros4mat import describe

        name, fields = describe(payload)
        if self.writer is not None:
            self.writer.write(t or 0.0, direction, payload)
        way = WIRE_DIR[direction]
        if self.json_out:
            record = {**self.stamp(t), "dir": way, "name": name, **fields}
            record.update(rounded(self.stamp(t)))  # a field of the message never hides it
            if self.hex_out:
                record["hex"] = payload.hex()
            line = json.dumps(record, default=str)
        else:
            text = " ".join(f"{k}={v}" for k, v in fields.items())
            stamp = f"{t:10.6f}" if t is not None else f"{'-':>10}"
            line = f"{stamp} {'->' if way == 'c2s' else '<-'} {name:<14} {text}"
            if self.hex_out:
                line += "\n" + " " * 14 + payload[:256].hex(" ")
        sys.stdout.write(line + "\n")
        sys.stdout.flush()
        self.printed += 1
