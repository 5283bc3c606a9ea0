"""Helpers shared by the message specs."""

from __future__ import annotations

import enum
import struct
from typing import Any, NoReturn, TypeVar

from construct import ConstructError

from robocli.errors import ProtocolError

E = TypeVar("E", bound=enum.IntEnum)

#: What the decoders' foreign machinery raises on bytes that do not fit a declaration:
#: construct's errors, ``struct``, slicing past the end, bad enum values, bad UTF-8. Decoders
#: catch exactly these at their boundary and raise :class:`ProtocolError` instead.
DECODE_ERRORS: tuple[type[Exception], ...] = (
    ConstructError,
    struct.error,
    IndexError,
    KeyError,
    ValueError,  # UnicodeDecodeError is one
    OverflowError,
)


class PartialFrame:
    """What every pure-Python framer keeps between two ``feed`` calls: the bytes of the frame
    not complete yet. Gives them the ``pending`` and ``reset`` of
    :class:`robocli.core.Framer`'s interface; a framer with more state between frames
    extends :meth:`reset`."""

    def __init__(self) -> None:
        self._buf = bytearray()

    @property
    def pending(self) -> int:
        """Bytes of a frame not complete yet."""
        return len(self._buf)

    def reset(self) -> None:
        """Forget the partial frame (the counters are kept)."""
        self._buf.clear()


def plain(obj: Any) -> Any:
    """A parsed ``construct`` value as plain dicts/lists (private ``_io`` keys dropped)."""
    if isinstance(obj, dict):
        return {k: plain(v) for k, v in obj.items() if not k.startswith("_")}
    if isinstance(obj, list):
        return [plain(v) for v in obj]
    return obj


def enum_or_int(kind: type[E], value: int) -> E | int:
    """``kind(value)`` when ``value`` is a member, else ``value`` itself (undefined ids are
    legal on the wire and kept as plain ints)."""
    try:
        return kind(value)
    except ValueError:
        return value


def enum_name(kind: type[enum.IntEnum], value: int, fallback: str) -> str:
    """The member name of ``value`` in ``kind``, or ``fallback`` when it has none."""
    try:
        return kind(value).name
    except ValueError:
        return fallback


def undecodable(what: str, data: bytes | bytearray | memoryview, exc: BaseException) -> NoReturn:
    """Raise the :class:`ProtocolError` of a packet that does not decode.

    ``what`` names the packet (``"ARCOS SIP"``), ``data`` is shown as its first bytes, ``exc``
    (one of :data:`DECODE_ERRORS`) gives the reason and stays the cause.
    """
    why = str(exc).splitlines()[0].strip() if str(exc).strip() else type(exc).__name__
    head = bytes(data[:24]).hex(" ")
    more = " ..." if len(data) > 24 else ""
    raise ProtocolError(f"undecodable {what} ({len(data)} B: {head}{more}): {why}") from exc


#: A robocli server that cannot take a client (a single-client robot already held, the
#: connection limit reached) sends one ASCII line ``robocli-refused: <reason>\n`` and closes.
#: No robot protocol has a word for "busy", and this line is garbage to every framer, so a
#: client of another make only sees a dropped link, while a robocli client shows the reason.
REFUSAL_PREFIX = b"robocli-refused: "
REFUSAL_MAX = 200  #: bytes of reason at most


def refusal_line(reason: str) -> bytes:
    """The bytes a server sends before closing a link it refuses."""
    text = reason.encode("ascii", "replace")[:REFUSAL_MAX].replace(b"\n", b" ")
    return REFUSAL_PREFIX + text + b"\n"


def find_refusal(data: bytes | bytearray) -> str | None:
    """The reason of a refusal line within ``data`` (what a client read before the link
    dropped), or None when there is none."""
    at = data.rfind(REFUSAL_PREFIX)
    if at < 0:
        return None
    line = bytes(data[at + len(REFUSAL_PREFIX) :]).split(b"\n", 1)[0]
    return line[:REFUSAL_MAX].decode("ascii", "replace").strip() or "refused"
