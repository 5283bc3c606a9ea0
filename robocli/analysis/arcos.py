"""ARCOS packets named and decoded (``robocli dump pioneer``): by handshake phase (SYNC0-2
and their replies, then commands and SIPs), with a simulator's own commands named as the
simulators name them."""

from __future__ import annotations

from typing import Any

from robocli.analysis.packets import Packet
from robocli.devices.pioneer.simulated import SIMULATOR_NAMES
from robocli.errors import ProtocolError
from robocli.protocols import arcos
from robocli.protocols.arcos import Command, PacketType

__all__ = ["ArcosDecoder", "guess_direction"]

#: Command argument markers: int >= 0, int < 0, string.
_ARG_MARKS = (0x3B, 0x1B)
_STRING_MARK = 0x2B
#: What commands 35-38 mean to a simulator (MobileSim/AMRISim's SRISim laser compatibility,
#: docs/protocols/arcos-sim.md section 1); a real robot reads them as ADSEL, ...
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


class ArcosDecoder:
    """Names and decodes the ARCOS payloads of one session, in order (a packet's name
    depends on the handshake phase, and on whether the robot said it is a simulator).
    Call it as ``decoder(direction, payload, t)``: "tx", "rx", or "?" for a raw capture."""

    def __init__(self) -> None:
        self.in_session = False
        self.simulator = False  #: the robot said it is a simulator (name, CONFIG serial)

    def __call__(self, direction: str, payload: bytes, t: float | None) -> Packet:
        if direction == "?":
            direction = guess_direction(payload, self.in_session)
        name, fields = self.describe(direction, payload)
        return Packet(t, direction, name, fields, arcos.frame(payload), type=payload[0])

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
