"""The sensor hub client: ros4mat v3 over TCP, ``from robocli import Hub``.

>>> with Hub.connect("127.0.0.1") as hub:          # doctest: +SKIP
...     hub.subscribe("imu", rate=200)
...     data, t = hub.read("imu")                   # 9 x N, (N,)
...     hub.read("imu").accel                        # 3 x N

Every call is one request, read in the caller's thread (:class:`~robocli.devices.session.
Session` leader/follower): ros4mat has no unsolicited messages. Requests are byte for byte
those of the original MATLAB client (``docs/protocols/ros4mat.md`` section 7). Replies are
decoded as NumPy views over the received bytes (:mod:`robocli.devices.hub.decode`).

The jobs behind :class:`Hub` have their own modules: the link, its handshake and its
requests (:mod:`robocli.devices.hub.link`), the SUBSCRIBE settings
(:mod:`robocli.devices.hub.subscription`) and the hub's clock
(:mod:`robocli.devices.hub.clock`): ``Reading.t`` is on the client's clock unless
``hub_clock=True``, by an offset estimated from every reply's send time and slewed so that
sample times never step back between reads.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np

from robocli.addresses import parse_device_url
from robocli.devices import simulators
from robocli.devices.base import (
    ListenerHandle,
    SessionDevice,
    close_simulator,
    not_over_zenoh,
    pick_kind,
    renamed_argument,
)
from robocli.devices.hub.clock import CLOCK_SLEW, CLOCK_STEP, CLOCK_WINDOW, ClockSync
from robocli.devices.hub.decode import HEADER, Reading, align_readings, body_of, decode_reading
from robocli.devices.hub.link import (
    MAX_TOKEN,
    NO_HUB_HINT,
    handshake,
    header_only,
    is_reply,
    open_hub,
    open_session,
    parse_hub,
    request,
    token_bytes,
    unanswered,
)
from robocli.devices.hub.subscription import (
    raw_frame_bytes,
    resolution,
    subscribe_body,
    subscribe_request,
)
from robocli.devices.listeners import FrameListener, Listeners
from robocli.devices.session import LinkStats, Session
from robocli.errors import DeviceError, InvalidArgument, ProtocolError
from robocli.protocols.ros4mat import MsgType, SerialStatus, encode_request, sensor_type
from robocli.transports import Transport

#: ``ZenohHub.connect``, which ``Hub.connect("zenoh/NAME")`` calls: put here by
#: :mod:`robocli.devices.hub.over_zenoh` (imported with this package), whose ZenohHub is a Hub
#: and so cannot be imported from here.
ZENOH_HUB: list[Callable[..., Hub]] = []


class Hub(SessionDevice):
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
        self._session = session
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
        #: whether the hub answers a refused DOUT_CTRL or UNSUBSCRIBE with an error reply
        #: (robocli's hub, which stamps its CONNECT_ACK; the original server answers neither
        #: and stamps only data replies): those requests are then fenced, and refusals raise
        self.answers_refusals = False

    # ------------------------------------------------------------------ connecting

    @classmethod
    def connect(
        cls,
        url: str | None = None,
        port: int | None = None,
        *,
        compress: bool = False,
        timeout: float = 5.0,
        client_id: int = 0,
        clock: Callable[[], float] = time.time,
        hub_clock: bool = False,
        token: bytes | str | None = None,
        listeners: Iterable[FrameListener] = (),
        host: str | None = None,
        zenoh: str | None = None,
    ) -> Hub:
        """Connect to the hub at ``url`` (``HOST[:PORT]`` or ``tcp://HOST:PORT``; ``port``
        default 1500; default 127.0.0.1) and send CONNECT. ``sim://`` starts the built-in
        simulated hub in-process on loopback (closed with the client); a hub's Zenoh
        front-end, ``zenoh/NAME`` (``zenoh/NAME?zenoh=ENDPOINT``, or the endpoint or JSON5
        file as ``zenoh=``), gives a :class:`~robocli.devices.hub.over_zenoh.ZenohHub`.
        ``host`` is the deprecated old name of ``url``.
        ``compress``: the hub zlib-compresses every reply.
        ``client_id``: re-attach to that client's buffers. ``clock``: the client's clock
        (seconds, like :func:`time.time`). ``token``: the shared secret of a hub started
        with one (``robocli serve --token-file``), sent after CONNECT's 2-byte body; a
        ``str`` is sent UTF-8 encoded. Without it (or with a wrong one) a hub with a token
        refuses settings changes and serial commands ("unauthorized"); pulls and silent
        subscribes work. ``listeners`` see every frame from the first (CONNECT) on.
        Raises :class:`TransportError` when nobody listens,
        :class:`TimeoutError` when the hub does not answer."""
        text = renamed_argument("Hub.connect", "host", "url", host, url, "127.0.0.1")
        if text.startswith("zenoh/"):
            not_over_zenoh(text, "hub", port=port, compress=compress, client_id=client_id)
            assert ZENOH_HUB, "robocli.devices.hub imports over_zenoh, which sets it"
            zhub = ZENOH_HUB[0](text, zenoh=zenoh, timeout=timeout, clock=clock,
                                hub_clock=hub_clock, token=token)  # fmt: skip
            for listener in listeners:
                zhub.add_listener(listener)
            return zhub
        if zenoh is not None:
            raise InvalidArgument(f"{text!r}: zenoh= is for a zenoh/NAME URL")
        if text == "sim" or text.startswith("sim://"):
            where = parse_device_url(text, what="hub URL")
            return simulators.connect_to(  # type: ignore[no-any-return]
                "hub", where, lambda sim: cls.connect(
                    sim.url, compress=compress, timeout=timeout, client_id=client_id,
                    clock=clock, hub_clock=hub_clock, token=token, listeners=listeners),
            )  # fmt: skip
        secret = token_bytes(token)
        h, p = parse_hub(text)
        if port is not None:
            p = port
        transport = open_hub(h, p, timeout)
        return cls.from_transport(
            transport, compress=compress, timeout=timeout, client_id=client_id,
            clock=clock, hub_clock=hub_clock, token=secret or None, listeners=listeners,
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
        listeners: Iterable[FrameListener] = (),
    ) -> Hub:
        """Like :meth:`connect` over an open transport (the hub owns it from now on)."""
        try:
            secret = token_bytes(token)
        except InvalidArgument:
            transport.close()
            raise
        session = open_session(transport)
        for listener in listeners:
            session.listeners.add(listener)
        header, t0, t1 = handshake(
            session, client_id=client_id, compress=compress, token=secret, clock=clock,
            timeout=timeout,
        )  # fmt: skip
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
        return request(self.session, packet, reply, self.timeout)

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
        body = subscribe_request(name, rate, buffer=buffer, poll=poll, **params)
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
        """Send a request that has no reply in ros4mat, fenced when the hub answers
        refusals (:func:`~robocli.devices.hub.link.unanswered`): its refusal raises."""
        unanswered(self.session, packet, kind, client_id=self.client_id, timeout=self.timeout,
                   fenced=self.answers_refusals)  # fmt: skip

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
        packet = header_only(kind, self.client_id)
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
            reading.t = self.sync.client_times(key, reading.hub_t)
        reading.lost = self._count_lost(key, reading.hub_t)
        return reading

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
        frame = self.session.request(packet, is_reply(MsgType.SERIAL_ANS), self.timeout + timeout)
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

    def close(self, stop: bool | None = None, *, quit: bool | None = None) -> None:
        """Send QUIT (the hub forgets this client; ``stop=False`` keeps its buffers for a
        reconnect with :attr:`client_id`) and close the link, bounded; then the simulator of
        a ``sim://`` URL. Idempotent. ``quit`` is the deprecated old name of ``stop``."""
        send_quit = renamed_argument("Hub.close", "quit", "stop", quit, stop, True)
        try:
            self.session.close((header_only(MsgType.QUIT, self.client_id),) if send_quit else ())
        finally:
            close_simulator(self)

    #: the in-process simulator of a ``sim://`` URL (None otherwise), closed with the hub
    simulator: simulators.Simulator | None = None

    def add_listener(self, listener: FrameListener, *, kind: str = "frames") -> ListenerHandle:
        """Call ``listener(direction "tx"/"rx", frame, t)`` for every frame sent or
        received; returns a handle whose ``remove()`` takes it off. One that raises is
        logged once, counted in ``stats.listener_errors``, never stops the client."""
        return self._add_listener(listener, kind)

    def _listeners_of(self, kind: str) -> Listeners[Any]:
        pick_kind(kind, ("frames",), "Hub")
        return self.session.listeners

    @property
    def session(self) -> Session:
        """The link to the hub."""
        return self._session

    def __repr__(self) -> str:
        return f"<Hub {self.url} client {self.client_id}>"


__all__ = [
    "CLOCK_SLEW",
    "CLOCK_STEP",
    "CLOCK_WINDOW",
    "MAX_TOKEN",
    "NO_HUB_HINT",
    "ClockSync",
    "Hub",
    "Reading",
    "align_readings",
    "parse_hub",
    "raw_frame_bytes",
    "resolution",
    "subscribe_body",
]
