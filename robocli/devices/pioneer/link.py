"""ARCOS on a :class:`~robocli.devices.session.Session`: packet naming, the stop sequences,
the SYNC handshake and the CONFIG request (used before and after the reader thread runs),
and the link's counters (:class:`PioneerStats`)."""

from __future__ import annotations

import contextlib
import logging
import time
from collections import deque
from collections.abc import Iterator
from typing import Any

from construct import ConstructError

from robocli.devices.pioneer.state import RobotIdentity
from robocli.devices.session import LinkStats, Session
from robocli.errors import (
    ConnectionLost,
    DeviceError,
    InvalidArgument,
    ProtocolError,
    TimeoutError,
    UnknownRobotError,
)
from robocli.protocols import arcos
from robocli.protocols.arcos import Command, PacketType
from robocli.protocols.common import find_refusal, plain
from robocli.robots.pioneer import ROBOT_PARAMS, RobotParams

log = logging.getLogger("robocli.devices.pioneer")

#: What stops a robot at once (sent when a client thread fails).
EMERGENCY_STOP = (
    arcos.encode_command(Command.VEL, 0),
    arcos.encode_command(Command.RVEL, 0),
)
#: What :meth:`Pioneer.close` sends: stop, motors off, end the session.
STOP_SEQUENCE = (
    *EMERGENCY_STOP,
    arcos.encode_command(Command.ENABLE, 0),
    arcos.encode_command(Command.CLOSE, 1),
)
CONFIG_REQUEST = arcos.encode_command(Command.CONFIG, 1)


_HISTORY = 100_000  #: samples kept in each timing history of :class:`PioneerStats`


class PioneerStats(LinkStats):
    """Link counters (see :class:`~robocli.devices.session.LinkStats`) plus the Pioneer's:
    SIPs received, keep-alives sent, dead-man stops, watchdog trips (this program stalled),
    laser scans completed and dropped (incomplete or garbled), and bounded timing
    histories."""

    _COUNTERS: tuple[str, ...] = (
        *LinkStats._COUNTERS, "sips", "keepalives", "deadman_stops", "watchdog_trips",
        "laser_scans", "laser_dropped",
    )  # fmt: skip

    def __init__(self) -> None:
        super().__init__()
        self.sips = 0
        self.keepalives = 0
        self.deadman_stops = 0
        self.watchdog_trips = 0  #: stalls of this program past the robot's watchdog
        self.laser_scans = 0
        self.laser_dropped = 0
        #: reader CPU seconds per SIP (decode + state update; thread CPU time, so waiting
        #: for the GIL is not counted), most recent last
        self.sip_work: deque[float] = deque(maxlen=_HISTORY)
        #: monotonic send times of keep-alive packets (PULSE or set-point refresh)
        self.keepalive_times: deque[float] = deque(maxlen=_HISTORY)
        #: monotonic send times of every packet (what the robot's watchdog sees)
        self.tx_times: deque[float] = deque(maxlen=_HISTORY)
        #: monotonic receive times of SIPs
        self.sip_times: deque[float] = deque(maxlen=_HISTORY)


def payload_of(frame: bytes) -> bytes:
    """Type byte + data of one ARCOS frame (``FA FB N ... ck ck``)."""
    return frame[3:-2]


# Packet names by type byte, computed once: naming is on every packet's path (statistics).
_TX_NAMES = tuple(arcos.packet_name(t, from_client=True) for t in range(256))
_RX_NAMES = tuple(arcos.packet_name(t, from_client=False) for t in range(256))


def name_of(payload: bytes, direction: str) -> str:
    return (_TX_NAMES if direction == "tx" else _RX_NAMES)[payload[0]]


def is_config(frame: bytes) -> bool:
    return frame[3] == PacketType.CONFIG


def parse_body(decl: Any, payload: bytes, what: str) -> Any:
    """``decl.parse`` of a packet's data as plain values; a :class:`ProtocolError` naming
    ``what`` when the bytes do not fit."""
    try:
        return plain(decl.parse(payload[1:]))
    except (ConstructError, UnicodeDecodeError, ValueError) as exc:
        why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ProtocolError(f"undecodable {what} packet {payload[:24].hex(' ')}: {why}") from None


#: Host baud rates in HOSTBAUD's codes (0=9600 ... 4=115200).
BAUD_CODES = {9600: 0, 19200: 1, 38400: 2, 57600: 3, 115200: 4}
#: The order in which the vendor SDK sprays CLOSE when a serial robot stays silent.
_PROBE_ORDER = (9600, 38400, 115200, 19200, 57600)


def _serial_port(session: Session) -> Any | None:
    """The pyserial port under ``session`` when its baud rate can be changed, else None."""
    port = getattr(session.transport, "port", None)
    return port if port is not None and hasattr(port, "baudrate") else None


def busy_refusal(url: str, exc: ConnectionLost) -> DeviceError | None:
    """What a link reset or closed by the peer during the handshake usually means (a real
    robot, or its serial-to-network bridge, holding another client, gives no reason): a
    :class:`DeviceError` saying so, or None for another loss."""
    text = str(exc).lower()
    if "reset" in text:
        how = "reset"
    elif "closed by the peer" in text:
        how = "closed"
    else:
        return None
    return DeviceError(
        f"{url}: the connection was {how} during the handshake; this usually means the "
        "robot is busy: another client holds it (close that program, or wait 2 s for "
        "the robot's watchdog to end its session, then retry)"
    )


def handshake(session: Session, timeout: float) -> RobotIdentity:
    """SYNC0/1/2 with retries; CLOSE a session that an earlier client left open.
    A server that refuses the link (robot busy) raises :class:`DeviceError` with its reason,
    or with what a reset without one usually means (:func:`busy_refusal`).

    On a serial port that stays silent at the configured rate, the other rates are probed
    in turn, as the vendor SDK does: CLOSE then SYNC0 at each; the port stays at the rate
    that answers."""
    url = session.transport.url
    deadline = time.monotonic() + timeout
    step = tried = misses = 0
    port = _serial_port(session)
    rates: list[int] = []
    if port is not None:
        rates = [port.baudrate] + [r for r in _PROBE_ORDER if r != port.baudrate]
    while time.monotonic() < deadline:
        tried += 1
        wait = min(1.0, max(0.05, deadline - time.monotonic()))
        if port is not None and misses >= 2 and step == 0:
            rates.append(rates.pop(0))  # the configured rate first, then the others
            log.info("%s: no answer at %d baud; trying %d", url, port.baudrate, rates[0])
            port.baudrate = rates[0]
            session.send(arcos.encode_command(Command.CLOSE, 1))
            wait = min(wait, 0.5)
        try:
            frame = session.request(arcos.encode_command(step), lambda f: True, wait)
        except TimeoutError:
            step = 0  # silence: start again
            misses += 1
            continue
        except ConnectionLost as exc:
            reason = find_refusal(session.raw_tail())
            if reason is not None:
                raise DeviceError(f"{url}: {reason}") from None
            raise busy_refusal(url, exc) or exc from None
        misses = 0
        payload = payload_of(frame)
        if payload[0] & 0xF0 == 0x30:
            log.info("robot is already in a session: sending CLOSE and re-syncing")
            session.send(arcos.encode_command(Command.CLOSE, 1))
            _drain(session, 0.2)
            step = 0
            continue
        if payload[0] != step:
            step = 0  # out of sequence: start again
            continue
        if step < 2:
            step += 1
            continue
        reply = parse_body(arcos.SyncReply, payload, "SYNC2")
        return RobotIdentity(str(reply["name"]), str(reply["type"]), str(reply["subtype"]))
    raise TimeoutError(
        f"{url}: no robot answering the ARCOS handshake ({tried} SYNC packets in {timeout:g} s)"
    )


def _drain(session: Session, seconds: float) -> None:
    """Read and drop whatever arrives for ``seconds`` (the old session's last SIPs)."""
    try:
        session.request(None, lambda f: False, seconds)
    except TimeoutError:
        pass
    session.framer.reset()


def request_config(session: Session, timeout: float) -> dict[str, Any] | None:
    """CONFIG, re-requested every 0.3 s as ARIA does; None when the robot sends none."""
    deadline = time.monotonic() + timeout
    while (left := deadline - time.monotonic()) > 0:
        try:
            frame = session.request(CONFIG_REQUEST, is_config, min(0.3, left))
        except TimeoutError:
            continue
        return dict(parse_body(arcos.CONFIG, payload_of(frame), "CONFIG"))
    return None


def params_for(subtype: str, identity: RobotIdentity) -> RobotParams:
    params = ROBOT_PARAMS.get(subtype.lower())
    if params is None:
        known = ", ".join(sorted(ROBOT_PARAMS))
        raise UnknownRobotError(
            f"robot {identity.name!r} reports subtype {identity.subtype!r}, which robocli has "
            f"no parameters for (known: {known}); pass subtype=... or params=RobotParams(...)"
        )
    return params


def switch_baud(session: Session, config: dict[str, Any] | None, rate: int) -> bool:
    """After CONFIG, move a serial link to ``rate`` with HOSTBAUD as the vendor SDK does:
    only when the robot allows it (CONFIG ``reset_baud`` == 2) and ``rate`` is faster than
    the current one. Sends PULSE at the new rate and takes any packet within 0.9 s as
    success; else goes back to the old rate. Returns True when the link was switched."""
    port = _serial_port(session)
    if rate not in BAUD_CODES:
        raise InvalidArgument(f"baud rate {rate} is not one of {sorted(BAUD_CODES)}")
    if port is None or config is None or config.get("reset_baud") != 2:
        return False
    old = int(port.baudrate)
    if rate <= old:
        return False
    session.send(arcos.encode_command(Command.HOSTBAUD, BAUD_CODES[rate]))
    time.sleep(0.05)  # let the command leave the UART at the old rate
    port.baudrate = rate
    try:
        session.request(arcos.encode_command(Command.PULSE), lambda f: True, 0.9)
    except TimeoutError:
        log.warning("%s: no answer at %d baud after HOSTBAUD; back to %d",
                    session.transport.url, rate, old)  # fmt: skip
        port.baudrate = old
        return False
    log.info("%s: switched to %d baud", session.transport.url, rate)
    return True


@contextlib.contextmanager
def explain_refusal(url: str) -> Iterator[None]:
    """Around connecting: a link reset or closed by the peer during the handshake becomes
    the :class:`~robocli.errors.DeviceError` of
    :func:`busy_refusal` (the Pioneer's handshake does this
    itself; other paths may lose the link around it)."""
    try:
        yield
    except ConnectionLost as exc:
        raise busy_refusal(url, exc) or exc from None
