"""The sensor hub client: ros4mat v3 over TCP, ``from robocli import Hub``.

>>> with Hub.connect("127.0.0.1") as hub:          # doctest: +SKIP
...     hub.subscribe("imu", rate=200)
...     data, t = hub.read("imu")                   # 9 x N, (N,)
...     hub.read("imu").accel                        # 3 x N

Every call is one request, read in the caller's thread (:class:`~robocli.devices.session.
Session` leader/follower): ros4mat has no unsolicited messages. Requests are byte for byte
those of the original MATLAB client (``shared/protocols/ros4mat.md`` section 7). Replies are
decoded as NumPy views over the received bytes (:mod:`robocli.devices.hub.decode`).

**Clock offset.** Every data reply carries the hub's send time; each pull gives one NTP-style
sample ``offset = packet_timestamp - (t_request + t_reply) / 2`` whose error is at most half
the round trip. The estimate is the sample with the smallest round trip among the last
:data:`CLOCK_WINDOW` pulls (a min-RTT filter), and ``Reading.t`` is on the client's clock
(``hub_t - offset``) unless ``hub_clock=True``. The offset applied follows the estimate by
slewing (:data:`CLOCK_SLEW`), so that sample times never step back between reads.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from robocli.core import Framer
from robocli.devices.hub.decode import HEADER, Reading, align_readings, body_of, decode_reading
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
    PARAMS,
    PORT,
    PROTOCOL_VERSION,
    MsgType,
    SerialStatus,
    adc_freq_send_default,
    encode_request,
    sensor_type,
)
from robocli.transports import (
    InvalidURL,
    Transport,
    format_address,
    open_transport,
    parse_address,
)

#: Pulls whose round trips the clock filter looks at.
CLOCK_WINDOW = 64
#: How fast sample times follow a new clock-offset estimate: at most this many seconds per
#: second of hub time (1 %), so that they never step back between reads (see :meth:`Hub.read`).
CLOCK_SLEW = 0.01
#: A new estimate that puts sample times later by more than this is stepped to at once
#: (times only jump forward); smaller ones, and every one that puts them earlier, are slewed.
CLOCK_STEP = 0.128
#: The longest token :meth:`Hub.connect` sends (it rides in CONNECT, under the hub's 64 KiB
#: request limit).
MAX_TOKEN = 4096
#: What to do when no hub listens at an address.
NO_HUB_HINT = "start one with `robocli serve --sim`"
#: Sensors whose subscribe params carry a ``freq_send`` (the driver's batch rate).
_WITH_FREQ_SEND = (MsgType.ADC, MsgType.IMU, MsgType.GPS, MsgType.BATTERY)
_CAMERAS = (MsgType.WEBCAM, MsgType.WEBCAM_STEREO, MsgType.KINECT, MsgType.KINECT_DEPTH)
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


def _u16(name: str, value: Any, low: int = 0) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InvalidArgument(f"{name} must be a number, not {value!r}")
    if int(value) != value or not low <= value <= 0xFFFF:
        raise InvalidArgument(f"{name} must be an integer in {low}..65535, not {value!r}")
    return int(value)


def resolution(text: str) -> tuple[int, int]:
    """The original client's rule: ``'640x480'`` -> width ⌊640/20⌋·20 clamped to 160..1600,
    height 3/4 of it (4:3 only)."""
    head = text.lower().split("x", 1)[0].strip()
    digits = ""
    for ch in head:
        if not ch.isdigit():
            break
        digits += ch
    width = min(1600, max(160, (int(digits or 0) // 20) * 20))
    return width, width * 3 // 4


def _camera_params(kind: MsgType, fps: int, params: dict[str, Any]) -> dict[str, Any]:
    res = params.pop("resolution", None)
    width, height = resolution(res) if res is not None else (320, 240)
    width = _u16("width", params.pop("width", width))
    height = _u16("height", params.pop("height", height))
    quality = _u16("quality", params.pop("quality", 0))
    if quality > 100:
        raise InvalidArgument(f"quality must be 0 (raw) or 1..100 (JPEG), not {quality}")
    roi = params.pop("roi", None)
    if kind == MsgType.WEBCAM:
        return {
            "fps": fps, "width": width, "height": height, "id": params.pop("id", 0),
            "compression": quality, "exposure": params.pop("exposure", 300),
            "use_roi": int(roi is not None), "roi": list(roi or (0, 0, 0, 0)),
        }  # fmt: skip
    if kind == MsgType.WEBCAM_STEREO:
        roi_right = params.pop("roi_right", None)
        return {
            "fps": fps, "width": width, "height": height,
            "id_left": params.pop("id_left", 0), "id_right": params.pop("id_right", 1),
            "compression": quality,
            "exposure_left": params.pop("exposure_left", 300),
            "exposure_right": params.pop("exposure_right", 300),
            "use_roi": int(roi is not None),
            "roi_left": list(roi or (0, 0, 0, 0)), "roi_right": list(roi_right or roi or (0,) * 4),
        }  # fmt: skip
    roi_rgb = params.pop("roi_rgb", None)
    return {  # the original client always sends send_rgb = send_depth = fps_depth = 0
        "fps_rgb": fps, "width_rgb": width, "height_rgb": height,
        "send_rgb": params.pop("send_rgb", 0), "id": params.pop("id", 0),
        "send_depth": params.pop("send_depth", 0), "fps_depth": params.pop("fps_depth", 0),
        "compression_rgb": quality, "use_roi_depth": int(roi is not None),
        "roi_depth": list(roi or (0,) * 4), "use_roi_rgb": int(roi_rgb is not None),
        "roi_rgb": list(roi_rgb or (0,) * 4),
    }  # fmt: skip


def subscribe_body(
    sensor: str | int,
    rate: float | None = None,
    *,
    buffer: int | None = None,
    poll: int | None = None,
    **params: Any,
) -> dict[str, Any]:
    """The SUBSCRIBE body the original client sends (for :func:`encode_request`).

    ``rate`` None: a silent subscribe (join the current settings). ``buffer`` defaults to
    ``rate`` (one second); ``poll`` is the driver's batch rate in Hz, an integer 0..65535
    (``freqSend`` of adc, imu, gps, battery: default ⌊rate/4 + 10⌋, an explicit value is
    clamped to ``rate``). ``params``: ``channels`` (ADC
    mask, default 0xFF); cameras ``resolution='640x480'`` or ``width``/``height``, ``id``,
    ``quality`` (0 raw, 1..100 JPEG), ``exposure``, ``roi``; stereo ``id_left``/``id_right``,
    ``exposure_left``/``exposure_right``; Kinect ``send_rgb``, ``send_depth``,
    ``fps_depth``, ``roi_rgb``.
    """
    kind = sensor_type(sensor)
    if kind not in PARAMS:
        raise InvalidArgument(f"sensor: {kind.name} cannot be subscribed to")
    if rate is None:
        if params or buffer is not None or poll is not None:
            raise InvalidArgument("rate: a silent subscribe (no rate) takes no other setting")
        return {"sensor": kind, "silent": 1, "buffer_size": 0, "params": None}
    freq = _u16("rate", rate, 1)
    size = freq if buffer is None else int(buffer)
    if isinstance(buffer, bool) or not 1 <= size <= 0xFFFFFFFF:
        raise InvalidArgument(f"buffer must be a positive number of samples, not {buffer!r}")
    extra = dict(params)
    values: dict[str, Any]
    if kind in _CAMERAS:
        values = _camera_params(kind, freq, extra)
    else:
        values = {"freq_acquisition": freq}
        if kind in _WITH_FREQ_SEND:
            send = adc_freq_send_default(freq) if poll is None else min(_u16("poll", poll), freq)
            values["freq_send"] = send
        if kind == MsgType.ADC:
            mask = _u16("channels", extra.pop("channels", 0xFF))
            if not 1 <= mask <= 0xFF:  # the CLI's rule too: a mask selects some channel
                raise InvalidArgument(
                    f"channels must be an 8-bit mask with a channel set (1..0xff), not {mask:#x}"
                )
            values["channels"] = mask
    if extra:
        raise InvalidArgument(f"{next(iter(extra))}: not a setting of {kind.name.lower()}")
    return {"sensor": kind, "silent": 0, "buffer_size": size, "params": values}


def raw_frame_bytes(body: Mapping[str, Any]) -> int:
    """Bytes one raw camera sample takes in a reply (0: not a raw camera subscription)."""
    p = body.get("params")
    kind = body["sensor"]
    if not isinstance(p, Mapping) or kind not in _CAMERAS:
        return 0
    if kind == MsgType.KINECT or kind == MsgType.KINECT_DEPTH:
        if p["compression_rgb"]:
            return 0
        return int(p["width_rgb"]) * int(p["height_rgb"]) * 5 + 44
    if p["compression"]:
        return 0
    one = int(p["width"]) * int(p["height"]) * 3 + 22
    return 2 * one if kind == MsgType.WEBCAM_STEREO else one


class ClockSync:
    """NTP-style offset of the hub's clock from the client's (min-RTT filter)."""

    def __init__(self, window: int = CLOCK_WINDOW) -> None:
        self._samples: deque[tuple[float, float]] = deque(maxlen=window)
        self._lock = threading.Lock()
        self.offset: float | None = None
        self.rtt: float | None = None

    def add(self, t_request: float, t_reply: float, hub_time: float) -> None:
        """One exchange: client times around it and the hub's send time in the reply."""
        if hub_time == 0.0 or not math.isfinite(hub_time):  # no send time, or a broken one
            return
        rtt = t_reply - t_request
        with self._lock:
            self._samples.append((rtt, hub_time - (t_request + t_reply) / 2))
            self.rtt, self.offset = min(self._samples)


class Hub:
    """A client of a ros4mat v3 sensor hub (``robocli serve`` or the original server)."""

    def __init__(
        self,
        session: Session,
        client_id: int,
        *,
        compress: bool,
        timeout: float,
        clock: Callable[[], float],
        hub_clock: bool,
    ) -> None:
        self.session = session
        self.client_id = client_id
        self.compress = compress
        self.timeout = timeout
        self.clock = clock
        self.hub_clock = hub_clock
        self.sync = ClockSync()
        self._subscribed: dict[str, MsgType] = {}
        self._lost: dict[str, int] = {}
        self._last_t: dict[str, float] = {}  # hub time of the last sample read, per sensor
        self._period: dict[str, float] = {}  # sample period (s): asked, then as seen
        self._since: dict[str, tuple[float, int]] = {}  # hub time of subscribing, buffer
        self._mapped: dict[str, tuple[float, float]] = {}  # last sample: hub t, offset used
        #: whether the hub answers a refused DOUT_CTRL or UNSUBSCRIBE with an error reply
        #: (robocli's hub, which stamps its CONNECT_ACK; the original server answers neither
        #: and stamps only data replies): those requests are then fenced, and refusals raise
        self.answers_refusals = False

    # ------------------------------------------------------------------ connecting

    @classmethod
    def connect(
        cls,
        host: str = "127.0.0.1",
        port: int | None = None,
        *,
        compress: bool = False,
        timeout: float = 5.0,
        client_id: int = 0,
        clock: Callable[[], float] = time.time,
        hub_clock: bool = False,
        token: bytes | str | None = None,
    ) -> Hub:
        """Connect to the hub at ``host`` (``HOST[:PORT]`` or ``tcp://HOST:PORT``; ``port``
        default 1500) and send CONNECT. ``compress``: the hub zlib-compresses every reply.
        ``client_id``: re-attach to that client's buffers. ``clock``: the client's clock
        (seconds, like :func:`time.time`). ``token``: the shared secret of a hub started
        with one (``robocli serve --token-file``), sent after CONNECT's 2-byte body; a
        ``str`` is sent UTF-8 encoded. Without it (or with a wrong one) a hub with a token
        refuses settings changes and serial commands ("unauthorized"); pulls and silent
        subscribes work. Raises :class:`TransportError` when nobody listens,
        :class:`TimeoutError` when the hub does not answer."""
        secret = _token_bytes(token)
        h, p = parse_hub(host)
        if port is not None:
            p = port
        try:
            transport = open_transport(f"tcp://{format_address(h, p)}", timeout=timeout)
        except InvalidURL:
            raise
        except TransportError as exc:  # the transport's hint names robots, not hubs
            text = str(exc)
            reason = text.split(": ", 1)[-1].split(" (", 1)[0] if ": " in text else text
            raise TransportError(
                f"no hub at {format_address(h, p)} ({reason}); {NO_HUB_HINT}"
            ) from None
        return cls.from_transport(
            transport, compress=compress, timeout=timeout, client_id=client_id,
            clock=clock, hub_clock=hub_clock, token=secret or None,
        )  # fmt: skip

    @classmethod
    def from_transport(
        cls,
        transport: Transport,
        *,
        compress: bool = False,
        timeout: float = 5.0,
        client_id: int = 0,
        clock: Callable[[], float] = time.time,
        hub_clock: bool = False,
        token: bytes | str | None = None,
    ) -> Hub:
        """Like :meth:`connect` over an open transport (the hub owns it from now on)."""
        try:
            secret = _token_bytes(token)
        except InvalidArgument:
            transport.close()
            raise
        session = Session(
            transport,
            Framer("ros4mat"),
            on_frame=_ignore,
            name_of=packet_name,
            stats=LinkStats(),
            name="hub",
        )
        hello = {"protocol_version": PROTOCOL_VERSION, "compression": int(bool(compress))}
        connect = encode_request(MsgType.CONNECT, hello, client_id=client_id)
        if secret:  # after the 2-byte body; the header's size stays 1 record
            connect = encode_request(
                MsgType.CONNECT, connect[HEADER.size :] + secret, client_id=client_id
            )
        # No reader thread: ros4mat sends nothing unasked, every reply is read by the caller
        # that asked (a lost link shows at the next request). Measured with 40 clients
        # pulling 3 sensors at 20 Hz, the idle readers' wake-ups tripled the p99 pull.
        try:
            t0 = clock()
            reply = session.request(connect, _is(MsgType.CONNECT_ACK), timeout)
            t1 = clock()
            header, _ = body_of(reply)
        except ConnectionLost:
            reason = find_refusal(session.raw_tail())
            session.close()
            if reason is not None:
                raise DeviceError(f"{transport.url}: {reason}") from None
            raise
        except BaseException:
            session.close()
            raise
        session._raw_tail = None  # noqa: SLF001 - as Session.start() does: the link is up
        hub = cls(
            session, header[2], compress=compress, timeout=timeout, clock=clock,
            hub_clock=hub_clock,
        )  # fmt: skip
        hub.answers_refusals = bool(header[7])
        hub.sync.add(t0, t1, header[7])  # the first clock sample, before any data
        return hub

    @property
    def url(self) -> str:
        return self.session.transport.url

    @property
    def stats(self) -> LinkStats:
        return self.session.stats

    @property
    def clock_offset(self) -> float | None:
        """Hub clock minus client clock (seconds), None until a reply carried the hub's send
        time (robocli's hub stamps its CONNECT_ACK already; the original, data replies)."""
        return self.sync.offset

    # ------------------------------------------------------------------ requests

    def _request(self, packet: bytes, reply: MsgType) -> bytes:
        framer = self.session.framer
        refused = framer.stats.bad_lengths
        try:
            return self.session.request(packet, _is(reply), self.timeout)
        except TimeoutError:
            if framer.stats.bad_lengths == refused:
                raise
        # the reply was longer than any frame we accept: the rest of it cannot be framed
        exc = ProtocolError(
            f"{self.url}: the hub's {reply.name} reply exceeds {MAX_BODY_SIZE >> 20} MiB "
            "(pull more often or subscribe with a smaller buffer); link closed"
        )
        self.session.fail(exc)
        raise exc

    def subscribe(
        self,
        name: str,
        rate: float | None = None,
        *,
        buffer: int | None = None,
        poll: int | None = None,
        **params: Any,
    ) -> None:
        """Subscribe to ``name`` (adc, imu, gps, battery, computer, hokuyo, camera,
        camera_stereo, kinect; or robocli's names sysinfo, laser, stereo, depth) at ``rate``
        Hz keeping ``buffer`` samples; no ``rate``: a silent subscribe. See
        :func:`subscribe_body` for the settings. Raises :class:`DeviceError` when the hub
        refuses, :class:`InvalidArgument` for ``kinect_ir`` (ros4mat has no pull for it)."""
        if sensor_type(name) == MsgType.KINECT_DEPTH:
            raise InvalidArgument(
                f"sensor: {name!r} (0x28) has no data pull in ros4mat and no hub serves it; "
                "subscribe to 'kinect' (alias 'depth') for RGB and depth"
            )
        body = subscribe_body(name, rate, buffer=buffer, poll=poll, **params)
        frame = raw_frame_bytes(body)
        if frame and frame * body["buffer_size"] > MAX_BODY_SIZE:
            fits = max(1, MAX_BODY_SIZE // frame)
            if buffer is not None:
                raise InvalidArgument(
                    f"buffer: {buffer} raw frames of {frame} bytes exceed one reply's "
                    f"{MAX_BODY_SIZE >> 20} MiB; at most {fits}"
                )
            body["buffer_size"] = fits  # the default (1 s) would not fit in one reply
        packet = encode_request(MsgType.SUBSCRIBE, body, client_id=self.client_id)
        header, _ = body_of(self._request(packet, MsgType.SUBSCRIBE_ACK))  # errors raise
        key = name.lower()
        self._subscribed[key] = sensor_type(name)
        self._last_t.pop(key, None)  # new settings: gaps from the old ones are not losses
        self._period.pop(key, None)
        self._since.pop(key, None)
        if rate is not None:
            self._period[key] = 1.0 / float(rate)
            if header[7]:  # the hub's time of the subscription (robocli's hub sends it)
                self._since[key] = (float(header[7]), int(body["buffer_size"]))

    def unsubscribe(self, name: str) -> None:
        """Stop receiving ``name``. ros4mat has no reply to it; a hub that answers refusals
        (:attr:`answers_refusals`) is asked for one more reply, and its refusal raises
        :class:`DeviceError`."""
        kind = sensor_type(name)
        packet = encode_request(MsgType.UNSUBSCRIBE, {"sensor": kind}, client_id=self.client_id)
        try:
            self._unanswered(packet, MsgType.UNSUBSCRIBE)
        finally:
            self._subscribed.pop(name.lower(), None)
            self._last_t.pop(name.lower(), None)

    def _unanswered(self, packet: bytes, kind: MsgType) -> None:
        """Send a request that has no reply in ros4mat. To a hub that answers refusals,
        the :data:`_FENCE` follows in the same write; the hub answers in order, so its
        refusal of ``packet``, if any, is read before the fence's reply, and raised."""
        if not self.answers_refusals:
            self.session.send(packet)
            return
        refused: list[bytes] = []

        def fence_reply(frame: bytes) -> bool:
            if frame[0] == kind and frame[1]:
                refused.append(frame)
            return frame[0] == _FENCE

        fence = HEADER.pack(_FENCE, 0, self.client_id, 0, 0, 0, 0, 0.0)
        self.session.request(packet + fence, fence_reply, self.timeout)
        if refused:
            body_of(refused[0])  # raises DeviceError with the hub's text

    @property
    def lost(self) -> dict[str, int]:
        """Samples lost so far, by sensor name (as given to :meth:`read`): the gaps in the
        times of the samples read, over 1.5 sample periods (the period as subscribed, then
        as seen within a reading). ros4mat does not report them: the hub drops a client's
        oldest samples when its buffer (``subscribe(buffer=)``) overflows between two
        reads. Before the first sample read, samples dropped are counted from the time of
        the subscription when the first reading fills the buffer (a hub that stamps its
        SUBSCRIBE_ACK, as robocli's does)."""
        return dict(self._lost)

    def _count_lost(self, key: str, hub_t: np.ndarray[Any, Any]) -> int:
        """Samples missing before and within ``hub_t`` (the hub times of one reading)."""
        if not len(hub_t):
            return 0
        ts = np.asarray(hub_t, dtype=np.float64)
        if len(ts) >= 3:  # contiguous samples (one pull): their spacing is the rate's
            with np.errstate(all="ignore"):
                self._period[key] = float(np.median(np.diff(ts)))
        prev = self._last_t.get(key)
        self._last_t[key] = float(ts[-1])
        period = self._period.get(key)
        since = self._since.pop(key, None)
        if prev is None and since is not None and period and len(ts) >= since[1]:
            prev = since[0] - period  # a full first reading: it overflowed since subscribing
        if prev is not None:
            ts = np.concatenate(([prev], ts))
        if period is None or not period > 0 or len(ts) < 2:
            return 0
        with np.errstate(all="ignore"):  # a hub's times may be anything: count finite gaps
            gaps = np.diff(ts) / period
            gaps = np.rint(gaps[np.isfinite(gaps) & (gaps > 1.5)])
        lost = sum(int(g) - 1 for g in gaps.tolist())  # Python ints: no overflow
        if lost:
            self._lost[key] = self._lost.get(key, 0) + lost
        return lost

    def pull(self, name: str) -> bytes:
        """One data pull of ``name``: the raw reply frame (header + body). Feeds the clock
        filter."""
        kind = sensor_type(name)
        packet = HEADER.pack(kind, 0, self.client_id, 0, 0, 0, 0, 0.0)
        t0 = self.clock()
        frame = self._request(packet, kind)
        t1 = self.clock()
        self.sync.add(t0, t1, HEADER.unpack_from(frame, 0)[7])
        return frame

    def read(self, name: str) -> Reading:
        """Every new sample of ``name`` since the last read (a destructive pull): a
        :class:`Reading` that unpacks as ``data, t`` in the original client's shapes. Its
        ``lost`` counts the samples the hub dropped before them (see :attr:`lost`)."""
        frame = self.pull(name)
        key = name.lower()
        reading = decode_reading(frame, key, None)
        if not self.hub_clock:
            reading.t = self._client_times(key, reading.hub_t)
        reading.lost = self._count_lost(key, reading.hub_t)
        return reading

    def _client_times(self, key: str, hub_t: np.ndarray[Any, Any]) -> np.ndarray[Any, Any]:
        """``hub_t`` on the client's clock, never earlier than the times already returned.

        The clock-offset estimate changes between reads (by up to a few milliseconds early
        in a session, as faster round trips come in): applied as is, a sample could get an
        earlier time than the previous read's last one. Each sensor's mapping instead starts
        from the offset applied to its last sample and moves toward the estimate by at most
        :data:`CLOCK_SLEW` seconds per second of hub time (a slew: within a reading and
        across reads, times keep their order and their spacing within 1 %). A first reading
        takes the estimate as is; an estimate that puts times later by over
        :data:`CLOCK_STEP` s is stepped to (forward only)."""
        h: np.ndarray[Any, Any] = np.asarray(hub_t, dtype=np.float64)
        target = self.sync.offset
        if target is None:  # nothing to map with yet: the hub's times as they are
            same: np.ndarray[Any, Any] = h.copy()
            return same
        anchor = self._mapped.get(key)
        if anchor is None or anchor[1] == target or anchor[1] - target > CLOCK_STEP:
            t: np.ndarray[Any, Any] = h - target  # the common case: nothing to slew
            if len(h) and math.isfinite(h[-1]):
                self._mapped[key] = (float(h[-1]), target)
            elif len(finite := np.flatnonzero(np.isfinite(h))):
                self._mapped[key] = (float(h[finite[-1]]), target)
            return t
        h0, o0 = anchor
        with np.errstate(invalid="ignore"):  # NaN hub times map to NaN
            reach = CLOCK_SLEW * np.maximum(h - h0, 0.0)
            offsets = o0 + np.clip(target - o0, -reach, reach)
        finite = np.flatnonzero(np.isfinite(h) & np.isfinite(offsets))
        if len(finite):
            last = finite[-1]
            self._mapped[key] = (float(h[last]), float(offsets[last]))
        slewed: np.ndarray[Any, Any] = h - offsets
        return slewed

    def read_aligned(
        self,
        names: Sequence[str],
        *,
        rate: float | None = None,
        reference: str | None = None,
        tolerance: float | None = None,
    ) -> dict[str, Any]:
        """Read ``names`` and put them on one time base (the C alignment).

        ``rate``: a uniform grid over the span every sensor covers; ``reference``: the
        times of that sensor (one of ``names``). Numeric sensors are linearly interpolated
        (:func:`~robocli.core.align_linear`); images and laser scans take the nearest
        sample within ``tolerance`` (default: one grid step), NaN/zero where none is.
        Returns ``{"t": times, name: data (fields x M)...}``.
        """
        if isinstance(names, str) or not names:
            raise InvalidArgument(
                f"read_aligned: give a list of sensor names (['adc', 'imu']), not {names!r}"
            )
        if (rate is None) == (reference is None):
            raise InvalidArgument("read_aligned: give either rate or reference")
        if reference is not None and reference not in names:
            raise InvalidArgument(f"reference: {reference!r} is not one of {list(names)}")
        readings = {name: self.read(name) for name in names}
        return align_readings(readings, rate=rate, reference=reference, tolerance=tolerance)

    def serial(
        self,
        port: str,
        data: bytes = b"",
        *,
        baud: int = 9600,
        parity: bool = False,
        stop_bits: int = 1,
        recv: int = 0,
        timeout: float = 1.0,
        close_after: bool = False,
    ) -> bytes:
        """Write ``data`` to the hub's serial ``port`` and read up to ``recv`` bytes within
        ``timeout`` s (SERIAL_CMD). A timeout returns what arrived; a port the hub will not
        open raises :class:`DeviceError`."""
        if not 0 <= len(data) <= 1024 or not 0 <= recv <= 1024:
            raise InvalidArgument("serial: at most 1024 bytes sent and received per call")
        if not 0 <= timeout < 32767:
            raise InvalidArgument(f"timeout must be 0..32767 s, not {timeout!r}")
        raw_port = port.encode()
        cmd = {
            "port_length": len(raw_port), "speed": int(baud), "parity": int(bool(parity)),
            "stop_bits": int(stop_bits), "send_length": len(data), "read_length": int(recv),
            "read_timeout_sec": int(timeout), "read_timeout_usec": int(timeout % 1 * 1e6),
            "close_after": int(bool(close_after)),
        }  # fmt: skip
        packet = encode_request(
            MsgType.SERIAL_CMD,
            {"cmd": cmd, "port": raw_port, "data": bytes(data)},
            client_id=self.client_id,
        )
        # the hub waits for the port up to `timeout` before it answers
        frame = self.session.request(packet, _is(MsgType.SERIAL_ANS), self.timeout + timeout)
        _header, body = body_of(frame)
        if len(body) < 5:
            raise ProtocolError(f"ros4mat SERIAL_ANS body of {len(body)} bytes")
        status, length = int(np.int8(body[0])), int.from_bytes(body[1:5], "little")
        payload = bytes(body[5 : 5 + length])
        if status in (SerialStatus.OK, SerialStatus.TIMEOUT):
            return payload
        why = {int(SerialStatus.NO_OPEN): "could not open", int(SerialStatus.BAD_SELECT): "failed"}
        raise DeviceError(f"hub serial port {port}: {why.get(status, str(status))}", status)

    def digital_out(self, d0: int, d1: int, d2: int, d3: int) -> None:
        """Set the ADC board's digital outputs D0..D3. ros4mat has no reply to it; a hub
        that answers refusals (:attr:`answers_refusals`, robocli's) is asked for one more
        reply, and its refusal raises :class:`DeviceError` (a hub with a token refuses a
        client without it: "unauthorized"; a hub whose ADC has no outputs)."""
        body = {"d0": int(d0), "d1": int(d1), "d2": int(d2), "d3": int(d3)}
        packet = encode_request(MsgType.DOUT_CTRL, body, client_id=self.client_id)
        self._unanswered(packet, MsgType.DOUT_CTRL)

    def close(self, quit: bool = True) -> None:  # noqa: A002 - the protocol's word
        """Send QUIT (the hub forgets this client; ``quit=False`` keeps its buffers for a
        reconnect with :attr:`client_id`) and close the link, bounded."""
        stop = (HEADER.pack(MsgType.QUIT, 0, self.client_id, 0, 0, 0, 0, 0.0),) if quit else ()
        self.session.close(stop)

    def __enter__(self) -> Hub:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<Hub {self.url} client {self.client_id}>"


def _token_bytes(token: bytes | str | None) -> bytes:
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


def _ignore(frame: bytes, t: float) -> None:
    """Frames nobody asked for (none in ros4mat) are counted by the session, not kept."""


def _is(kind: int) -> Callable[[bytes], bool]:
    return lambda frame: frame[0] == kind


def packet_name(payload: bytes, direction: str) -> str:
    """The message name of a packet (for the session's statistics)."""
    try:
        return MsgType(payload[0]).name
    except (ValueError, IndexError):
        return "unknown"


__all__ = [
    "CLOCK_WINDOW",
    "ClockSync",
    "Hub",
    "Reading",
    "align_readings",
    "parse_hub",
    "raw_frame_bytes",
    "resolution",
    "subscribe_body",
]
