"""ros4mat on a :class:`~robocli.devices.session.Session`: the hub's address and token,
opening the link and the CONNECT handshake, one request and its reply (a reply too long to
frame fails the link), header-only requests, the fence after a request that has no reply,
packet names for the statistics.

Part of the hub client (:mod:`robocli.devices.hub.client`, which re-exports
:func:`parse_hub`, :data:`MAX_TOKEN` and :data:`NO_HUB_HINT`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from robocli.core import Framer
from robocli.devices.hub.decode import HEADER, body_of
from robocli.devices.session import LinkStats, Session
from robocli.errors import (
    ConnectionLost,
    DeviceError,
    InvalidArgument,
    ProtocolError,
    TimeoutError,
    TransportError,
)
from robocli.protocols.common import find_refusal
from robocli.protocols.ros4mat import (
    MAX_BODY_SIZE,
    PORT,
    PROTOCOL_VERSION,
    MsgType,
    encode_request,
)
from robocli.transports import (
    InvalidURL,
    Transport,
    format_address,
    open_transport,
    parse_address,
)

__all__ = [
    "MAX_TOKEN", "NO_HUB_HINT", "handshake", "header_only", "is_reply", "open_hub", "open_session",
    "packet_name", "parse_hub", "request", "token_bytes", "unanswered",
]  # fmt: skip

#: The longest token :meth:`Hub.connect` sends (it rides in CONNECT, under the hub's 64 KiB
#: request limit).
MAX_TOKEN = 4096
#: What to do when no hub listens at an address.
NO_HUB_HINT = "start one with `robocli serve --sim`"
#: The fence sent after a request that has no reply in ros4mat (DOUT_CTRL, UNSUBSCRIBE) to a
#: hub that answers refusals: a pull of 0x28, which ros4mat never serves (robocli's hub
#: answers it with an error reply and changes nothing). The hub answers in order, so a
#: refusal of the request arrives before the fence's reply.
_FENCE = MsgType.KINECT_DEPTH


def parse_hub(address: str, default_port: int = PORT) -> tuple[str, int]:
    """``HOST``, ``HOST:PORT``, ``[IPv6]:PORT``, ``:PORT`` or ``tcp://HOST:PORT`` ->
    (host, port), by :func:`robocli.transports.parse_address` (host default 127.0.0.1);
    :class:`~robocli.transports.InvalidURL` (a usage error) if malformed."""
    return parse_address(address, default_port, default_host="127.0.0.1", what="hub")


def token_bytes(token: bytes | str | None) -> bytes:
    """The token as sent (b"" for none); :class:`InvalidArgument` for an empty, too long or
    non-bytes one."""
    if token is None:
        return b""
    if isinstance(token, str):
        token = token.encode()
    if not isinstance(token, (bytes, bytearray)):
        raise InvalidArgument(f"token must be bytes or str, not {type(token).__name__}")
    if not token or len(token) > MAX_TOKEN:
        raise InvalidArgument(f"token must be 1..{MAX_TOKEN} bytes, not {len(token)}")
    return bytes(token)


def open_hub(host: str, port: int, timeout: float) -> Transport:
    """The TCP transport to the hub at ``host``:``port``; :class:`TransportError` saying
    how to start a hub when nobody listens there."""
    try:
        return open_transport(f"tcp://{format_address(host, port)}", timeout=timeout)
    except InvalidURL:
        raise
    except TransportError as exc:  # the transport's hint names robots, not hubs
        text = str(exc)
        reason = text.split(": ", 1)[-1].split(" (", 1)[0] if ": " in text else text
        raise TransportError(
            f"no hub at {format_address(host, port)} ({reason}); {NO_HUB_HINT}"
        ) from None


def open_session(transport: Transport) -> Session:
    """The hub's session over ``transport`` (not started: see :func:`handshake`)."""
    return Session(
        transport,
        Framer("ros4mat"),
        on_frame=_ignore,
        name_of=packet_name,
        stats=LinkStats(),
        name="hub",
    )


def handshake(
    session: Session,
    *,
    client_id: int,
    compress: bool,
    token: bytes,
    clock: Callable[[], float],
    timeout: float,
) -> tuple[tuple[Any, ...], float, float]:
    """Send CONNECT (``token``, if any, after its 2-byte body) and read CONNECT_ACK: its
    header and the client's ``clock`` before and after the exchange. A hub's refusal
    raises :class:`DeviceError`; any failure closes the session."""
    hello = {"protocol_version": PROTOCOL_VERSION, "compression": int(bool(compress))}
    connect = encode_request(MsgType.CONNECT, hello, client_id=client_id)
    if token:  # after the 2-byte body; the header's size stays 1 record
        connect = encode_request(
            MsgType.CONNECT, connect[HEADER.size :] + token, client_id=client_id
        )
    # No reader thread: ros4mat sends nothing unasked, every reply is read by the caller
    # that asked (a lost link shows at the next request). Measured with 40 clients
    # pulling 3 sensors at 20 Hz, the idle readers' wake-ups tripled the p99 pull.
    try:
        t0 = clock()
        reply = session.request(connect, is_reply(MsgType.CONNECT_ACK), timeout)
        t1 = clock()
        header, _ = body_of(reply)
    except ConnectionLost:
        reason = find_refusal(session.raw_tail())
        session.close()
        if reason is not None:
            raise DeviceError(f"{session.transport.url}: {reason}") from None
        raise
    except BaseException:
        session.close()
        raise
    session._raw_tail = None
    return header, t0, t1


def request(session: Session, packet: bytes, reply: MsgType, timeout: float) -> bytes:
    """Send ``packet`` and read the ``reply`` frame within ``timeout`` s. A reply longer
    than any frame accepted cannot be framed: :class:`ProtocolError`, and the link fails."""
    framer = session.framer
    refused = framer.stats.bad_lengths
    try:
        return session.request(packet, is_reply(reply), timeout)
    except TimeoutError:
        if framer.stats.bad_lengths == refused:
            raise
    # the reply was longer than any frame we accept: the rest of it cannot be framed
    exc = ProtocolError(
        f"{session.transport.url}: the hub's {reply.name} reply exceeds "
        f"{MAX_BODY_SIZE >> 20} MiB (pull more often or subscribe with a smaller buffer); "
        "link closed"
    )
    session.fail(exc)
    raise exc


def unanswered(
    session: Session, packet: bytes, kind: MsgType, *, client_id: int, timeout: float,
    fenced: bool,
) -> None:  # fmt: skip
    """Send a request that has no reply in ros4mat. ``fenced`` (a hub that answers
    refusals): the :data:`_FENCE` follows in the same write; the hub answers in order, so
    its refusal of ``packet``, if any, is read before the fence's reply, and raised."""
    if not fenced:
        session.send(packet)
        return
    refused: list[bytes] = []

    def fence_reply(frame: bytes) -> bool:
        if frame[0] == kind and frame[1]:
            refused.append(frame)
        return frame[0] == _FENCE

    fence = header_only(_FENCE, client_id)
    session.request(packet + fence, fence_reply, timeout)
    if refused:
        body_of(refused[0])  # raises DeviceError with the hub's text


def header_only(kind: int, client_id: int) -> bytes:
    """A request that is a header alone (a data pull, QUIT, the fence), packed directly:
    a pull is on every read's path."""
    return HEADER.pack(kind, 0, client_id, 0, 0, 0, 0, 0.0)


def _ignore(frame: bytes, t: float) -> None:
    """Frames nobody asked for (none in ros4mat) are counted by the session, not kept."""


def is_reply(kind: int) -> Callable[[bytes], bool]:
    """Whether a frame is of type ``kind`` (the reply a request waits for)."""
    return lambda frame: frame[0] == kind


def packet_name(payload: bytes, direction: str) -> str:
    """The message name of a packet (for the session's statistics)."""
    try:
        return MsgType(payload[0]).name
    except (ValueError, IndexError):
        return "unknown"
