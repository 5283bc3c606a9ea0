"""robocli's serial streaming extension of ros4mat v3 (not in the original protocol).

ros4mat's ``SERIAL_CMD`` is one request and one bounded reply (at most 1 KiB, a read
timeout): a program cannot use it as a serial line. robocli adds five message ids, in the
classes the original server and framer use (0x0X requests, 0x1X acks, 0x2X data), none of
which the original client sends, so ``SERIAL_CMD`` and every original message stay byte for
byte as they were::

    0x07 SERIAL_OPEN      client -> hub  SerialOpen body (below); reply SERIAL_OPEN_ACK.
                                         Again on an open stream: new line settings.
    0x17 SERIAL_OPEN_ACK  hub -> client  header only (size 0), or an error reply
    0x08 SERIAL_WRITE     client -> hub  the bytes to write (size 1, 1..MAX_STREAM_CHUNK
                                         bytes); no reply unless refused (error reply 0x08)
    0x09 SERIAL_CLOSE     client -> hub  header only; no reply. QUIT or a lost connection
                                         close the stream too
    0x2B SERIAL_DATA      hub -> client  bytes read from the port (size 1), pushed as they
                                         come, unasked; an error reply 0x2B ends the stream
                                         (the port failed)

``SerialOpen`` (7 bytes + the port name)::

    u32 speed (baud) | u8 byte_size (5..8) | char parity (N E O M S)
    | u8 stop_bits (tenths: 10, 15, 20) | u16 port length | port name (UTF-8)

Rules the hub enforces (:mod:`robocli.hub_server.serial`): the hub's token guards all three
requests as it guards ``SERIAL_CMD``; only the ports of its allow-list open; one stream per
port and per connection (``SERIAL_CMD`` on a streamed port is refused); a write body is at
most :data:`MAX_STREAM_CHUNK` bytes and is written to the port within a deadline sized to
the baud rate; what the hub pushes waits in the connection's bounded output queue (a client
that stops reading is dropped, as for any reply).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import construct as cs

__all__ = ["MAX_STREAM_CHUNK", "PARITIES", "STOP_BITS", "SerialOpen", "write_deadline"]

WRITE_SLACK_S = 1.0  #: a write's deadline beyond the time its bytes take on the line
MAX_STREAM_CHUNK = 4096
"""The most bytes one SERIAL_WRITE or SERIAL_DATA carries."""
PARITIES = "NEOMS"
"""pyserial's parity letters: none, even, odd, mark, space."""
STOP_BITS = {10: 1, 15: 1.5, 20: 2}
"""The ``stop_bits`` field (tenths) -> stop bits."""

SerialOpen = cs.Struct(
    "speed" / cs.Int32ul,
    "byte_size" / cs.Int8ul,
    "parity" / cs.PaddedString(1, "ascii"),
    "stop_bits" / cs.Int8ul,
    "port" / cs.PascalString(cs.Int16ul, "utf8"),
)
"""SERIAL_OPEN body: the line settings and the hub's port name."""


def write_deadline(settings: Mapping[str, Any], n: int) -> float:
    """Seconds the hub gives a write of ``n`` bytes to its port (pyserial ``settings``):
    twice their time on the line plus :data:`WRITE_SLACK_S`. A client waits for the hub to
    take a write a second longer (the hub drains what came before at the line's rate)."""
    bits = 1 + settings["bytesize"] + (settings["parity"] != "N") + settings["stopbits"]
    return float(WRITE_SLACK_S + 2.0 * n * bits / settings["baudrate"])
