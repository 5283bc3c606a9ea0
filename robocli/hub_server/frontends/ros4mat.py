"""The ros4mat v3 front-end of the hub: TCP (port 1500), many clients, wire-compatible.

Each connection has one thread (:class:`robocli.serving.server.Server`): it frames requests with
the C ros4mat framer (bounded by ``max_body``) and answers each one inline, as fast as they
arrive (the original served one request per connection per 5 ms loop). Everything about
sensors and clients is in :class:`robocli.hub_server.registry.SensorRegistry`; this module only
translates packets. Beyond ros4mat:

* every data reply carries the send time on the hub's clock (``packet_timestamp``);
* a malformed, compressed or unknown request gets an error reply (type = the request's); a
  stream that loses its framing (garbage, a header announcing more than the hub takes, a
  request left half-sent) is closed, after an error reply naming the request when a
  connected client's header announced too large a body: ros4mat has no sync marker, and
  what a rescan finds after garbage may be a phantom request (a QUIT that drops the
  client's subscriptions). A client that stops reading is dropped. No other client notices;
* optional shared-token authentication (off by default, as ros4mat had none): the token goes
  after the 2-byte ``msgConnect`` body of CONNECT (``size`` stays 1); without it, a
  non-silent SUBSCRIBE (it changes the sensor's settings for everyone), SERIAL_CMD and
  DOUT_CTRL get an error reply "unauthorized";
* client ids: CONNECT with the id of a client that is connected gets a new id (the original
  client sends its old id again after ``close``; it adopts the one in CONNECT_ACK), never
  that client. CONNECT with the id of a detached client (gone without QUIT) re-attaches to
  its buffers: without a token, as ros4mat, and so does any request carrying that id
  without CONNECT (anyone who knows or guesses the id can act as that client); with a token,
  only a CONNECT that presents the token re-attaches, and ids are random, not sequential;
* a pull of a sensor the client is not subscribed to is an empty reply (size 0), as the
  original server answered.
"""

from __future__ import annotations

import hmac
import logging
import struct
import threading
import time
import zlib
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from robocli.errors import DeviceError, InvalidArgument, ProtocolError
from robocli.hub_server.registry import ClientState, Pulled, SensorRegistry
from robocli.hub_server.serial import SerialStream, line_settings
from robocli.protocols import layout
from robocli.protocols.common import DECODE_ERRORS, undecodable
from robocli.protocols.ros4mat import (
    HEADER_SIZE,
    Compression,
    DigitalOut,
    Header,
    MsgType,
    SerialCmdRequest,
    SerialOpen,
    SubscribeRequest,
    encode_error,
    plain,
)
from robocli.serving.links import Link

__all__ = ["SENSOR_IDS", "PullTimes", "Ros4matSession", "body_parts", "pull_body"]

log = logging.getLogger("robocli.hub_server")

SENSOR_IDS: dict[int, str] = {
    MsgType.ADC: "adc",
    MsgType.IMU: "imu",
    MsgType.BATTERY: "battery",
    MsgType.GPS: "gps",
    MsgType.WEBCAM: "camera",
    MsgType.COMPUTER: "sysinfo",
    MsgType.HOKUYO: "laser",
    MsgType.KINECT: "depth",
    MsgType.WEBCAM_STEREO: "stereo",
}
"""ros4mat sensor id -> the hub's sensor name."""

_REPLY_TYPES: dict[int, int] = {
    MsgType.CONNECT: MsgType.CONNECT_ACK,
    MsgType.SUBSCRIBE: MsgType.SUBSCRIBE_ACK,
    MsgType.SERIAL_CMD: MsgType.SERIAL_ANS,
    MsgType.SERIAL_OPEN: MsgType.SERIAL_OPEN_ACK,
}
"""Request -> the type of its reply (an error reply has the type of the expected reply)."""

_REQUESTS = frozenset(
    [MsgType.CONNECT, MsgType.QUIT, MsgType.SUBSCRIBE, MsgType.UNSUBSCRIBE, MsgType.SERIAL_CMD,
     MsgType.DOUT_CTRL, MsgType.SERIAL_OPEN, MsgType.SERIAL_WRITE, MsgType.SERIAL_CLOSE,
     *SENSOR_IDS]
)  # fmt: skip
"""The message ids a client sends."""

_HEADER: struct.Struct = layout.struct_of(Header, "msgHeader")


def body_parts(pulled: Pulled) -> list[Any]:
    """The pieces of a data reply's body, as buffers over the pulled records (no copy): the
    records, or their info records then each frame's blobs at their used size."""
    rec, src = pulled.records, pulled.source
    if not src.blobs:
        return [rec.view(np.uint8).reshape(-1).data]
    parts: list[Any] = [rec["info"].tobytes()]  # stereo: two infos per frame, in order
    sizes = src.blob_sizes(rec).tolist()
    blobs = [rec[b] for b in src.blobs]
    for i, row in enumerate(sizes):
        for blob, size in zip(blobs, row, strict=True):
            parts.append(blob[i, :size].data)
    return parts


def pull_body(pulled: Pulled) -> bytes:
    """The body of a data reply (one copy out of the records)."""
    return b"".join(body_parts(pulled))


class PullTimes:
    """The server-side duration of the last :data:`SIZE` pulls (request framed -> reply
    built), for percentiles. Thread-safe, fixed memory."""

    SIZE = 1 << 16

    def __init__(self) -> None:
        self._d = np.zeros(self.SIZE, dtype=np.float64)
        self._n = 0
        self._lock = threading.Lock()

    def add(self, seconds: float) -> None:
        with self._lock:
            self._d[self._n % self.SIZE] = seconds
            self._n += 1

    def percentiles(self, qs: tuple[float, ...] = (50, 99, 100)) -> dict[str, float]:
        """``{"count": n, "p50": s, "p99": s, "p100": s}`` over the pulls kept."""
        with self._lock:
            d = self._d[: min(self._n, self.SIZE)].copy()
            n = self._n
        out: dict[str, float] = {"count": float(n)}
        for q in qs:
            out[f"p{q:g}"] = float(np.percentile(d, q)) if len(d) else 0.0
        return out


class Ros4matSession:
    """One ros4mat connection (its link's thread calls :meth:`on_frame` in order)."""

    def __init__(
        self,
        link: Link,
        hub: SensorRegistry,
        peer: str,
        token: bytes | None,
        serial: Any,
        times: PullTimes | None = None,
        *,
        admit: Callable[[Ros4matSession], str | None] | None = None,
        on_end: Callable[[Ros4matSession], None] | None = None,
        reap: Callable[[], object] | None = None,
        max_body: int | None = None,
    ) -> None:
        self.link, self.hub, self.peer = link, hub, peer
        self.address = link.address
        self.authorized = False  #: presented the hub's token (in its last CONNECT)
        self.last_request = time.monotonic()  #: when it last sent a request (monotonic s)
        self._admit = admit
        """Takes a client place for this connection: None, or why there is none."""
        self._admitted = False
        self._on_end = on_end
        self._reap = reap
        """Waits (bounded) for the connections whose peer has already closed to end."""
        self._max_body = max_body
        self._token = token
        self._serial = serial
        self._times = times or PullTimes()
        self.state: ClientState | None = None
        self.stream: SerialStream | None = None
        """The hub's serial port this connection streams (robocli's extension)."""

    # ---------------------------------------------------------------- replies

    def _cid(self) -> int:
        return self.state.id if self.state is not None else 0

    def _error(self, msg_type: int, text: str) -> bytes:
        log.info("%s: %s", self.peer, text)
        return encode_error(msg_type, text, client_id=self._cid())

    def _packet(self, msg_type: int, payload: bytes, size: int, since: float | None = None
                ) -> bytes:  # fmt: skip
        """A reply with ``size`` records, zlib-compressed if the client asked, sent now.

        Its time stamp is the middle of ``since`` (the hub's clock when the request was
        taken up) and now: the client maps the stamp onto the middle of its round trip, so
        a stamp taken after a long compression put its clock offset half of that late (4 to
        7 ms on megabyte camera replies)."""
        compress = bool(payload) and self.state is not None and self.state.compress
        wire = zlib.compress(payload) if compress else payload
        kind = Compression.ZLIB if compress else Compression.NONE
        now = self.hub.clock()
        stamp = now if since is None else (since + now) / 2
        head = _HEADER.pack(msg_type, 0, self._cid(), size, len(payload), len(wire), kind, stamp)
        return head + wire

    def _data(self, msg_type: int, pulled: Pulled, since: float) -> list[Any]:
        """A data reply as buffers: its header, then the records (no copy; the link writes
        them in one gathered write), or the header and the compressed body. Stamped as
        :meth:`_packet` says, ``since`` being when the pull began."""
        n = len(pulled.t)
        assert self.state is not None
        if self.state.compress and n:
            return [self._packet(msg_type, pull_body(pulled), n, since)]
        parts = body_parts(pulled)
        body = sum(p.nbytes if isinstance(p, memoryview) else len(p) for p in parts)
        stamp = (since + self.hub.clock()) / 2
        head = _HEADER.pack(msg_type, 0, self.state.id, n, body, body, 0, stamp)
        return [head, *parts]

    # ---------------------------------------------------------------- session protocol

    def drop(self, why: str) -> None:
        """Close this connection (the hub takes its place back)."""
        log.info("%s: closed: %s", self.peer, why)
        self.link.close()

    def on_frame(self, frame: bytes, now: float) -> bytes | None:
        self.last_request = now
        try:
            return self._handle(frame)
        except (ProtocolError, DeviceError, InvalidArgument) as exc:
            kind = frame[0] if frame else 0
            return self._error(_REPLY_TYPES.get(kind, kind), str(exc))

    def on_unframed(self, head: bytes) -> bytes | None:
        """The stream lost its framing at ``head``; the link closes after this reply. A
        connected client whose request header announced a body over the hub's limit is told
        so, by an error reply of its request's type (before CONNECT: closed unanswered)."""
        if self.state is None or self._max_body is None or len(head) < HEADER_SIZE:
            return None
        kind, error, _cid, size, _usize, csize, ctype, _ts = _HEADER.unpack_from(head)
        body = csize if size else 0
        if error or ctype > Compression.ZLIB or kind not in _REQUESTS or body <= self._max_body:
            return None  # not a request too large: garbage
        return self._error(_REPLY_TYPES.get(kind, kind), f"request body of {body} bytes is "
                           f"over this hub's limit of {self._max_body}; closing")  # fmt: skip

    def on_close(self) -> None:
        self._end_stream()
        if self.state is not None:
            self.hub.detach(self.state)
            log.info("%s: client %d detached (buffers kept)", self.peer, self.state.id)
        if self._admitted and self._on_end is not None:
            self._admitted = False
            self._on_end(self)

    def _enter(self) -> str | None:
        """Take a client place for this connection (once): None, or why there is none."""
        if not self._admitted:
            refused = self._admit(self) if self._admit is not None else None
            if refused is not None:
                return refused
            self._admitted = True
            self.link.establish()
        return None

    # ---------------------------------------------------------------- dispatch

    def _handle(self, frame: bytes) -> bytes | None:
        kind, error, cid, size, usize, csize, ctype, _ts = _HEADER.unpack_from(frame)
        body = frame[HEADER_SIZE:]
        if error or ctype != Compression.NONE or (size and usize != len(body)):
            return self._error(_REPLY_TYPES.get(kind, kind), "malformed request header")
        if kind == MsgType.CONNECT:
            return self._connect(cid, body)
        if self.state is None:
            # ros4mat: a request carrying a detached client's id re-attaches to it; not with a
            # token (a request cannot present it: CONNECT again with the token)
            if not cid or self._token is not None or not self.hub.detached(cid):
                return self._error(kind, "not connected: send CONNECT first")
            refused = self._enter()
            if refused is not None:
                return self._error(kind, refused)
            self.state = self.hub.attach(cid, self.peer)
            if self.state is None:
                return self._error(kind, "not connected: send CONNECT first")
        state = self.state
        if kind in SENSOR_IDS:
            name = SENSOR_IDS[kind]
            if body:
                return self._error(kind, "a data pull has no body")
            if name not in state.cursors:  # as the original: nothing queued, size 0
                return self._packet(kind, b"", 0)
            start, since = time.perf_counter(), self.hub.clock()
            # the copy a pull makes is charged to the output budget before it is made
            if not self.link.reserve(self.hub.pull_size(state, name)):
                return None  # no room, even after the clients that do not read: dropped
            try:
                parts = self._data(kind, self.hub.pull(state, name), since)
            finally:
                self.link.unreserve()  # the reply's queue is charged for what waits
            self._times.add(time.perf_counter() - start)
            self.link.send_parts(parts)  # after the replies to earlier frames
            return None
        if kind == MsgType.SUBSCRIBE:
            return self._subscribe(body)
        if kind == MsgType.UNSUBSCRIBE:
            if len(body) != 1:
                return self._error(kind, "UNSUBSCRIBE takes 1 byte")
            sensor = SENSOR_IDS.get(body[0])
            if sensor is not None:
                self.hub.unsubscribe(state, sensor)
            return None
        if kind == MsgType.QUIT:
            self._end_stream()
            self.hub.quit(state)
            self.state = None
            self.link.close()
            return None
        if kind == MsgType.DOUT_CTRL:
            self._authorize(kind)
            levels = _parse(DigitalOut, body, "DOUT_CTRL")
            self.hub.digital_out([levels[k] for k in ("d0", "d1", "d2", "d3")])
            return None
        if kind == MsgType.SERIAL_CMD:
            self._authorize(kind)
            return self._serial_cmd(body)
        if kind in (MsgType.SERIAL_OPEN, MsgType.SERIAL_WRITE, MsgType.SERIAL_CLOSE):
            self._authorize(kind)  # the token guards a stream as it guards SERIAL_CMD
            return self._stream_request(kind, body)
        return self._error(kind, f"unknown message id 0x{kind & 0xFF:02x}")

    def _authorize(self, kind: int) -> None:
        if self._token is not None and not (self.state is not None and self.state.authorized):
            raise DeviceError(f"unauthorized: {MsgType(kind).name} needs the hub's token")

    def _connect(self, cid: int, body: bytes) -> bytes:
        if len(body) < 2:
            return self._error(MsgType.CONNECT_ACK, "CONNECT body is 2 bytes")
        given = body[2:]
        authorized = (
            self._token is not None and bool(given) and hmac.compare_digest(given, self._token)
        )
        self.authorized = authorized  # which places it may take
        refused = self._enter()
        if refused is not None:
            return self._error(MsgType.CONNECT_ACK, refused)
        # with a token, only its holder may take a detached client's buffers (and rights)
        resume = self._token is None or authorized
        if self.state is not None:
            self.hub.detach(self.state)
            self.state = None
        if resume and cid and self.hub.in_use(cid) and self._reap is not None:
            self._reap()  # its connection may be closed, its end not handled yet
        self.state = self.hub.connect(cid, self.peer, body[1] == 1, resume=resume)
        self.state.authorized = authorized
        self.link.privileged = authorized  # the output budget cuts the others first
        return self._packet(MsgType.CONNECT_ACK, b"", 0)

    def _subscribe(self, body: bytes) -> bytes:
        kind = MsgType.SUBSCRIBE_ACK
        req = _parse(SubscribeRequest, body, "SUBSCRIBE")
        name = SENSOR_IDS.get(req["sensor"])
        if name is None:
            return self._error(kind, f"sensor 0x{req['sensor']:02x} is not served")
        params = req["params"]
        silent = bool(req["silent"])
        if not silent:
            self._authorize(MsgType.SUBSCRIBE)
            if not isinstance(params, Mapping):
                return self._error(kind, f"{name}: {req['params_size']} bytes of parameters "
                                   "do not match the sensor's")  # fmt: skip
        assert self.state is not None
        self.hub.subscribe(self.state, name, None if silent else params, req["buffer_size"])
        return self._packet(kind, b"", 0)

    def _serial_cmd(self, body: bytes) -> bytes:
        req = _parse(SerialCmdRequest, body, "SERIAL_CMD")
        if self._serial is None:
            raise DeviceError("this hub serves no serial port")
        status, data = self._serial.command(req)
        payload = struct.pack("<bI", status, len(data)) + data
        return self._packet(MsgType.SERIAL_ANS, payload, 1)

    # ---------------------------------------------------------------- serial stream

    def _stream_request(self, kind: int, body: bytes) -> bytes | None:
        """SERIAL_OPEN (open, or new settings), SERIAL_WRITE, SERIAL_CLOSE."""
        stream = self.stream
        if kind == MsgType.SERIAL_CLOSE:
            self._end_stream()
            return None
        if kind == MsgType.SERIAL_WRITE:
            if stream is None:
                raise DeviceError("no serial stream open: send SERIAL_OPEN first")
            stream.write(body)
            return None
        req = _parse(SerialOpen, body, "SERIAL_OPEN")
        settings = line_settings(req)
        if stream is not None and stream.name != req["port"]:
            raise DeviceError(f"this connection streams {stream.name!r}: close it first")
        if stream is not None:
            stream.apply(settings)
        elif self._serial is None:
            raise DeviceError("this hub serves no serial port")
        else:
            self.stream = SerialStream(self._serial, req["port"], settings, self._push,
                                       self._stream_failed)  # fmt: skip
        return self._packet(MsgType.SERIAL_OPEN_ACK, b"", 0)

    def _push(self, data: bytes) -> bool:
        """Bytes from the streamed port, sent unasked (the reader's thread)."""
        return self.link.send(self._packet(MsgType.SERIAL_DATA, data, 1))

    def _stream_failed(self, reason: str) -> None:
        self.link.send(self._error(MsgType.SERIAL_DATA, reason))
        self._end_stream()

    def _end_stream(self) -> None:
        stream, self.stream = self.stream, None
        if stream is not None:
            stream.close()


def _parse(decl: Any, body: bytes, what: str) -> dict[str, Any]:
    """A request body decoded with its declaration; :class:`ProtocolError` if it does not."""
    try:
        value: dict[str, Any] = plain(decl.parse(body))
    except DECODE_ERRORS as exc:
        undecodable(f"ros4mat {what}", body, exc)
    return value
