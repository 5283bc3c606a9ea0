"""Fuzz harnesses of the sensor hub's two input paths, client and server.

* ``decode-hub-reply``: a reply as the hub client receives it. A real :class:`~robocli.
  devices.hub.Hub` sits on one end of a socketpair; the input becomes one ros4mat reply frame
  (raw, zlib-compressed, or carrying JPEG frames) written on the other end before the client
  pulls, so the whole receive path runs: framing, the header, bounded inflation, the record
  and image decoders, the lost-sample count and the clock mapping. It must return a reading
  or raise a :class:`robocli.errors.RobocliError`.
* ``hub-server-requests``: a byte stream as the hub server receives it from one client. The
  bytes are framed as the server's links frame them (the C framer, the server's request
  limit) and each request goes to a real
  :class:`~robocli.hub_server.frontends.ros4mat.Ros4matSession` over the simulated sensors,
  in-process. The session must not raise, and every reply it sends must be exactly one ros4mat
  packet that decodes.

Any other exception, or a broken invariant (an ``AssertionError``), is a finding.
"""

from __future__ import annotations

import socket
import struct
import zlib
from collections.abc import Callable
from typing import Any

import numpy as np

from robocli.core import Framer
from robocli.devices.hub.client import Hub
from robocli.errors import RobocliError
from robocli.hub_server.frontends.ros4mat import PullTimes, Ros4matSession
from robocli.hub_server.registry import SensorRegistry
from robocli.hub_server.sources import SerialPorts, hub_sources
from robocli.protocols import ros4mat as r4m
from robocli.protocols.ros4mat import HEADER_SIZE, MsgType
from robocli.transports import SocketTransport

# ============================================================================ client side

#: The sensors a client pulls, as the low bits of an input's option byte pick them.
SENSORS: tuple[tuple[MsgType, str], ...] = (
    (MsgType.ADC, "adc"),
    (MsgType.IMU, "imu"),
    (MsgType.GPS, "gps"),
    (MsgType.COMPUTER, "computer"),
    (MsgType.BATTERY, "battery"),
    (MsgType.WEBCAM, "camera"),
    (MsgType.WEBCAM_STEREO, "camera_stereo"),
    (MsgType.HOKUYO, "hokuyo"),
    (MsgType.KINECT, "kinect"),
)
_OPT_SENSOR = 0x0F  # option bits: sensor index (modulo the number of sensors)
_OPT_ZLIB = 0x10  # deflate the body, so that the bytes reach the decoders through inflation
_OPT_HUB_CLOCK = 0x20  # read on the hub's clock (no mapping onto the client's)
_CONNECT_ACK_T = 1000.0  # the send time in the CONNECT_ACK: a hub that stamps its replies


class ClientRig:
    """A :class:`Hub` on a socketpair, subscribed to every sensor, and the hub's end."""

    def __init__(self) -> None:
        a, b = socket.socketpair()
        self.peer = b
        b.settimeout(5.0)
        b.sendall(r4m.encode_packet(MsgType.CONNECT_ACK, size=0, packet_timestamp=_CONNECT_ACK_T))
        self.hub = Hub.from_transport(SocketTransport(a, "pair://hub"), timeout=5.0)
        for _kind, name in SENSORS:
            b.sendall(r4m.encode_packet(MsgType.SUBSCRIBE_ACK, size=0, packet_timestamp=1.0))
            self.hub.subscribe(name, 100, buffer=4)
        self.drain()

    def drain(self) -> None:
        """Discard the requests the client sent."""
        self.peer.setblocking(False)
        try:
            while self.peer.recv(1 << 16):
                pass
        except BlockingIOError:
            pass
        finally:
            self.peer.settimeout(5.0)

    def close(self) -> None:
        self.hub.close(quit=False)
        self.peer.close()


_rig: ClientRig | None = None


def reply_frame(data: bytes) -> tuple[int, bytes]:
    """(sensor index, one reply frame the client's framer accepts whole) of an input: the
    option byte, then a 27-byte header and a body (missing header bytes are zeros)."""
    opt = data[0]
    index = (opt & _OPT_SENSOR) % len(SENSORS)
    kind = SENSORS[index][0]
    raw = data[1:]
    head = bytearray(raw[:HEADER_SIZE].ljust(HEADER_SIZE, b"\0"))
    body = bytes(raw[HEADER_SIZE:])
    _t, error, cid, size, usize, _csize, ctype, stamp = _HEADER.unpack(head)
    error &= 1  # the framer's rule: error 0/1, compression 0/1
    ctype &= 1
    if opt & _OPT_ZLIB and not error:
        size, usize, ctype = size or 1, len(body), 1
        body = zlib.compress(body)
    if not error and size == 0:
        body = b""  # size 0: no body on the wire
    if not error and ctype == 0:
        usize = len(body)  # a raw body is exactly its declared size
    head = _HEADER.pack(kind, error, cid, size, usize, len(body), ctype, stamp)
    return index, head + body


_HEADER = struct.Struct("<bbIIIIbd")  # msgHeader


def fuzz_hub_reply(data: bytes) -> None:
    """One input: one reply to a pull, through the client's whole receive path."""
    global _rig
    if not data:
        return
    index, frame = reply_frame(data)
    if _rig is None or not _rig.hub.session.alive:
        if _rig is not None:
            _rig.close()
        _rig = ClientRig()
    rig = _rig
    name = SENSORS[index][1]
    rig.hub.hub_clock = bool(data[0] & _OPT_HUB_CLOCK)
    rig.peer.sendall(frame)  # before the pull: the reply waits in the socket
    try:
        reading = rig.hub.read(name)
    except RobocliError:
        return
    finally:
        rig.drain()
    assert reading.t.shape == reading.hub_t.shape, (reading.t.shape, reading.hub_t.shape)
    assert reading.lost >= 0, reading.lost


def _records(kind: MsgType, n: int, t0: float = 10.0) -> bytes:
    rec = np.zeros(n, dtype=r4m.record_dtype(kind))
    rec["t"] = t0 + np.arange(n) * 0.01
    return rec.tobytes()


def _jpeg(w: int, h: int, level: int) -> bytes | None:
    try:
        from PIL import Image
    except ImportError:  # seeds without JPEG frames
        return None
    import io

    buf = io.BytesIO()
    Image.fromarray(np.full((h, w, 3), level, np.uint8)).save(buf, format="JPEG", quality=50)
    return buf.getvalue()


def _camera_body(kind: MsgType, n: int, jpeg: bool) -> bytes | None:
    w, h = 8, 6
    frames = 2 * n if kind == MsgType.WEBCAM_STEREO else n
    blobs = []
    for i in range(frames):
        blob = _jpeg(w, h, 40 * i) if jpeg else bytes([i]) * (w * h * 3)
        if blob is None:
            return None
        blobs.append(blob)
    info_dtype = r4m.record_dtype(kind)
    infos = np.zeros(frames, dtype=info_dtype)
    infos["width"], infos["height"], infos["channels"] = w, h, 3
    infos["size_data"] = [len(b) for b in blobs]
    infos["compression"] = 50 if jpeg else 0
    infos["t"] = 10.0 + np.arange(frames) // (2 if kind == MsgType.WEBCAM_STEREO else 1)
    return infos.tobytes() + b"".join(blobs)


def _kinect_body(n: int, jpeg: bool) -> bytes | None:
    w, h = 8, 6
    infos = np.zeros(n, dtype=r4m.record_dtype(MsgType.KINECT))
    blobs = []
    for i in range(n):
        rgb = _jpeg(w, h, 30 * i) if jpeg else bytes([i]) * (w * h * 3)
        if rgb is None:
            return None
        blobs.append(rgb + np.full((h, w), 1000 + i, "<u2").tobytes())
        infos["rgb"][i] = (w, h, 3, len(rgb), 50 if jpeg else 0, 10.0 + i)
        infos["depth"][i] = (w, h, 1, w * h * 2, 0, 10.0 + i)
    return infos.tobytes() + b"".join(blobs)


def _hokuyo_body(n: int, beams: int = 5) -> bytes:
    infos = np.zeros(n, dtype=r4m.record_dtype(MsgType.HOKUYO))
    infos["angle_min"], infos["angle_max"], infos["angle_increment"] = -1.0, 1.0, 0.5
    infos["range_max"], infos["size_data"] = 30.0, beams * 4
    infos["t"] = 10.0 + np.arange(n) * 0.025
    ranges = np.linspace(0.1, 5.0, n * beams, dtype="<f4")
    return infos.tobytes() + ranges.tobytes()


def reply_seeds() -> list[bytes]:
    """Valid replies of every sensor (1 and 3 records; raw, zlib and JPEG), as inputs."""
    out = []
    for index, (kind, _name) in enumerate(SENSORS):
        for n in (1, 3):
            bodies: list[bytes | None]
            if kind in (MsgType.WEBCAM, MsgType.WEBCAM_STEREO):
                bodies = [_camera_body(kind, n, False), _camera_body(kind, n, True)]
            elif kind == MsgType.KINECT:
                bodies = [_kinect_body(n, False), _kinect_body(n, True)]
            elif kind == MsgType.HOKUYO:
                bodies = [_hokuyo_body(n)]
            else:
                bodies = [_records(kind, n)]
            for body in bodies:
                if body is None:
                    continue
                frame = r4m.encode_packet(kind, body, size=n, packet_timestamp=10.5)
                out += [bytes((index,)) + frame, bytes((index | _OPT_ZLIB,)) + frame]
        out.append(bytes((index | _OPT_HUB_CLOCK,)) + r4m.encode_packet(kind, size=0))
        out.append(bytes((index,)) + r4m.encode_error(kind, "not subscribed to it"))
    return out


# ============================================================================ server side

_OPT_TOKEN = 0x01  # the hub has a token (the seeds' CONNECTs may carry it)
_OPT_FULL = 0x02  # the hub is full: the session answers every request with an error
_OPT_SERIAL = 0x04  # the hub serves a serial port (that does not exist)
TOKEN = b"fuzz-token"
MAX_REQUEST_BODY = 64 * 1024  # the hub's default request limit (robocli.hub_server.server)


class _Link:
    """What a :class:`Ros4matSession` sends, kept (the server's link writes it out)."""

    def __init__(self) -> None:
        self.sent: list[bytes] = []
        self.closed = False
        self.address = "127.0.0.1"  # the client's address (the places policy counts by it)
        self.privileged = False  # set by the session for a token holder

    def reserve(self, n: int) -> bool:
        """The server's output budget: a fuzzed input is one client, always within it."""
        return not self.closed

    def unreserve(self) -> None:
        """Give back what :meth:`reserve` charged."""

    def send(self, data: bytes) -> bool:
        self.sent.append(bytes(data))
        return not self.closed

    def send_parts(self, parts: Any) -> bool:
        return self.send(b"".join(bytes(p) for p in parts))

    def close(self) -> None:
        self.closed = True

    def establish(self) -> None:
        """The session completed its handshake (a server link stops counting it pending)."""


class ServerRig:
    """The hub's registry over the simulated sensors (small rings), shared by all inputs."""

    def __init__(self) -> None:
        self.registry = SensorRegistry(hub_sources(True), ring_budget=1 << 20, detached_ttl=600.0)
        self.times = PullTimes()
        self.serial = SerialPorts(("/nonexistent/robocli-fuzz-tty",))

    def forget_everyone(self) -> None:
        """Quit every client (connected or detached): their sensors stop."""
        ttl = self.registry.detached_ttl
        self.registry.detached_ttl = -1.0
        try:
            self.registry.expire()
        finally:
            self.registry.detached_ttl = ttl


_server: ServerRig | None = None


def check_reply(reply: bytes) -> None:
    """A reply is exactly one ros4mat packet, which decodes."""
    framer = Framer("ros4mat")
    frames = framer.feed(reply)
    assert len(frames) == 1 and framer.pending == 0, (reply[:64].hex(), len(frames))
    try:
        r4m.decode(reply)
    except RobocliError as exc:
        raise AssertionError(f"the hub sent a packet that does not decode: {exc}") from exc


def fuzz_hub_server(data: bytes) -> None:
    """Option byte, then the bytes one client sends: each request framed, then handled."""
    global _server
    if not data:
        return
    if _server is None:
        _server = ServerRig()
    rig = _server
    opt, stream = data[0], data[1:]
    link = _Link()
    session = Ros4matSession(
        link,  # type: ignore[arg-type]
        rig.registry,
        "fuzz",
        TOKEN if opt & _OPT_TOKEN else None,
        rig.serial if opt & _OPT_SERIAL else None,
        rig.times,
        admit=(lambda _session: "hub full: too many clients") if opt & _OPT_FULL else None,
    )
    framer = Framer("ros4mat", max_frame=HEADER_SIZE + MAX_REQUEST_BODY)
    try:
        for frame in framer.feed(stream):
            if link.closed:
                break
            reply = session.on_frame(frame, 0.0)
            if reply is not None:
                link.send(reply)
        for reply in link.sent:
            check_reply(reply)
    finally:
        session.on_close()
        state = session.state
        if state is not None:
            rig.registry.quit(state)
        rig.forget_everyone()


def request_seeds(frames: list[bytes]) -> list[bytes]:
    """Sessions made of the golden requests: CONNECT, a subscribe, pulls, the other
    commands, QUIT; with and without a token, full, with a serial port."""
    import reference

    golden = {name: f for kind, name, f in reference.golden_frames() if kind == "ros4mat"}
    connect, connect_zlib = golden["connect"], golden["connect_zlib"]
    token_connect = r4m.encode_request(MsgType.CONNECT, connect[HEADER_SIZE:] + TOKEN)
    subscribes = [f for name, f in golden.items() if name.startswith("subscribe_")]
    serial = r4m.encode_request(
        MsgType.SERIAL_CMD,
        {"cmd": {"port_length": 3, "speed": 9600, "parity": 0, "stop_bits": 1,
                 "send_length": 2, "read_length": 4, "read_timeout_sec": 0,
                 "read_timeout_usec": 1000, "close_after": 1},
         "port": b"tty", "data": b"hi"},
    )  # fmt: skip
    tail = golden["digital_out_1010"] + golden["unsubscribe_adc"] + golden["quit"]
    out = []
    for sub in subscribes:
        kind = sub[HEADER_SIZE]  # msgSubscribe.sensor
        pull = r4m.encode_packet(kind, size=0)
        for hello in (connect, connect_zlib, token_connect):
            out.append(bytes((0,)) + hello + sub + pull + pull + tail)
        out.append(bytes((_OPT_TOKEN,)) + token_connect + sub + pull + tail)
    out.append(bytes((_OPT_TOKEN,)) + connect + golden["subscribe_adc"] + tail)
    out.append(bytes((_OPT_FULL,)) + connect + golden["pull_adc"] + golden["quit"])
    out.append(bytes((_OPT_SERIAL,)) + connect + serial + golden["quit"])
    out.append(bytes((0,)) + b"".join(frames))  # every golden request, no CONNECT first
    return out


TARGETS: dict[str, tuple[Callable[[bytes], None], tuple[str, ...]]] = {
    "decode-hub-reply": (fuzz_hub_reply, ("ros4mat",)),
    "hub-server-requests": (fuzz_hub_server, ("ros4mat",)),
}


def seed_inputs(name: str, frames: list[bytes]) -> list[bytes]:
    """The seeds of a harness (``frames``: the golden ros4mat requests)."""
    if name == "decode-hub-reply":
        return reply_seeds()
    return request_seeds(frames)
