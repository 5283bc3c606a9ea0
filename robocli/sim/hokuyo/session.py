"""One client's SCIP 2.0 conversation with a simulated Hokuyo (:class:`ScipSession`).

The state machine of ``docs/protocols/scip2.md`` section 6: (SCIP 1.1 ->) IDLE (laser off)
-BM-> LASER ON -MD/MS/ME-> STREAMING -QT-> IDLE; TM0 -> TIME ADJUST (every other command
answered ``0E``, as UL observed for QT) -TM2-> IDLE; RS/RT -> IDLE with the timer at 0; RB
twice within 1 s -> reboot (timer 0, laser off, back to SCIP 1.1 on a profile that boots
there). Requests are checked field by field: ``0C``/``0D`` for too few/too many parameter
characters, ``0E`` for an unknown command (or GE/ME/RT on a model without them), ``01``..``07``
for the numeric fields of G*/M* (SPEC p.11/p.13), ``0G``/``0H`` for a ``;string`` too long or
with a bad character. In SCIP 1.1 every line but ``SCIP2.0`` is answered with the one-char
status ``E`` (how UL recognises 1.1). Every reply and every scan frame goes out whole or not
at all (:class:`~robocli.sim.hokuyo.output.FrameOutput`).

The UST and UTM-30LX-EW firmware (``model.state_commands``) also take ``%ST`` (the state, as
one 3-digit code: 000 standby, 002 time adjust, 003 single scan, 004 multi scan, 005 sleep;
hokuyolx's table) and ``%SL`` (sleep: laser off, motor stopped; from standby or measuring,
``10`` otherwise). QT, BM, MD/MS/ME, RS/RT/RB wake a sleeping sensor.

Time: a scan's stamp is the timer at the start of its measurement, and the scan a reply
carries was measured after the request that made it: GD/GS/GE answer with the latest scan
begun with the laser on (waiting for the first one after BM), MD streams the scans begun
after the command. The timer only moves forward, from 0 at RS/RT/RB.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np
import numpy.typing as npt

from robocli.protocols import scip2
from robocli.sim.hokuyo.model import HokuyoModel
from robocli.sim.hokuyo.output import FrameOutput

if TYPE_CHECKING:
    from robocli.serving.server import Link

__all__ = ["ScipSession", "Stream", "encode_array"]

RB_WINDOW_S = 1.0
MAX_BURST = 40  #: scans a late tick sends at most (a loaded machine's stall), the newest
#: Commands the simulator serves (multi-echo HD/HE/ND/NE is answered ``0E``).
_SUPPORTED = frozenset(("VV", "PP", "II", "BM", "QT", "RS", "RT", "RB", "TM", "SS", "CR",
                        "HS", "GD", "GS", "GE", "MD", "MS", "ME", "%ST", "%SL"))  # fmt: skip
#: handler names of the ``%`` commands
_HANDLER = {"%ST": "state", "%SL": "sleep"}


def status(code: str) -> bytes:
    """A status line: the two characters, their sum, LF."""
    return scip2.with_sum(code.encode())


def info(lines: list[str]) -> bytes:
    """``KEY:value;sum`` lines (the sum excludes the ``;``)."""
    out = []
    for line in lines:
        raw = line.encode("latin-1")
        out.append(raw + b";" + scip2.sum_char(raw) + b"\n")
    return b"".join(out)


class Scanner(Protocol):
    """What a session needs of its simulator (:class:`~robocli.sim.hokuyo.HokuyoSim`)."""

    model: HokuyoModel
    scip11: bool
    mute: bool
    ignore_qt: bool

    def now(self) -> float: ...
    def timer_ms(self, t: float | None = None) -> int: ...
    def scan_start(self, k: int) -> float: ...
    def latest_scan(self) -> int: ...
    def first_scan_from(self, t: float) -> int: ...
    def wait_scan(self, k: int) -> None: ...
    def reset_timer(self) -> None: ...
    def reboot(self) -> None: ...
    def scan_values(self) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]: ...
    def detach(self, session: ScipSession) -> None: ...


@dataclass
class Stream:
    """A running MD/MS/ME request."""

    kind: str
    head: bytes  #: the request's first 13 characters
    string: bytes  #: ``;string`` as sent, or empty
    start: int
    end: int
    cluster: int
    interval: int
    remaining: int | None  #: None: until QT
    next_k: int  #: the next scan to send


class ScipSession:
    """The protocol of one link to a :class:`Scanner` (a :class:`~robocli.sim.hokuyo.HokuyoSim`)."""

    def __init__(self, sim: Scanner, link: Link, *, tcp: bool) -> None:
        self.sim, self.link, self.tcp = sim, link, tcp
        self.model: HokuyoModel = sim.model
        self.lock = threading.Lock()
        self._sending = threading.Lock()  # the frames of one on_scans call go out together
        self.laser = False
        self.adjust = False  # TM0 .. TM2
        self.stream: Stream | None = None
        self.sleeping = False  # %SL .. a command that wakes it
        self.first_scan = 0  # the first scan measured with the laser on (since BM/MD)
        self._rb_at: float | None = None
        self.high_sensitivity = False
        self.frames_sent = 0
        self.out = FrameOutput(link)
        self._pending: tuple[int, Callable[[], bytes]] | None = None  # a G* waits for its scan

    @property
    def frames_dropped(self) -> int:
        """Scan frames not sent: the client read too slowly (dropped whole)."""
        return self.out.scans_dropped

    # ---------------------------------------------------------------- link thread

    def on_frame(self, frame: bytes, now: float) -> bytes | None:
        self.link.establish()  # a complete command line: the client keeps the laser
        if self.sim.mute:
            return None
        with self.lock:
            reply = self._handle(frame, now)
            pending, self._pending = self._pending, None
        if pending is not None:  # a single scan measured after the request: wait for it
            k, build = pending
            self.sim.wait_scan(k)
            with self.lock:
                reply = build()
        if reply:
            self.out.reply(reply)
        return None

    def on_close(self) -> None:
        with self.lock:
            self.stream = None
            self.laser = False
        self.sim.detach(self)

    # ---------------------------------------------------------------- ticker thread

    def on_scans(self, k_now: int) -> None:
        """Send the frames of the scans up to ``k_now`` (the latest complete) that are due.
        Two calls at once (a late tick) send their frames one call after the other, in order."""
        self.out.flush()  # what the line did not take last time goes first
        with self._sending:
            with self.lock:
                s = self.stream
                if s is None:
                    return
                if s.next_k < k_now - MAX_BURST:  # the simulator stalled: no flood of old scans
                    skip = (k_now - MAX_BURST - s.next_k) // (s.interval + 1) + 1
                    s.next_k += skip * (s.interval + 1)
                    self.out.dropped(skip)
                due: list[int] = []
                while s.next_k <= k_now and (s.remaining is None or len(due) < s.remaining):
                    due.append(s.next_k)
                    s.next_k += s.interval + 1
            for k in due:  # one write each: a pty's room is judged frame by frame
                with self.lock:
                    if self.stream is not s:  # QT, or a new MD, came in between
                        return
                    frame = self._frame(s, k)  # the count runs down even for a dropped one
                self.out.scan(frame)  # whole, or dropped whole (counted)

    def _frame(self, s: Stream, k: int) -> bytes:
        if s.remaining is None:
            left = 0
        else:
            s.remaining -= 1
            left = s.remaining
            if left == 0:
                self.stream, self.laser = None, False  # the laser is off after N scans
        echo = s.head + f"{left:02d}".encode() + s.string
        self.frames_sent += 1
        return echo + b"\n" + status("99") + self._data(s.kind, s.start, s.end, s.cluster, k)

    def _data(self, kind: str, start: int, end: int, cluster: int, k: int) -> bytes:
        """Timestamp line, data lines and the empty line of scan ``k``."""
        sim = self.sim
        ranges, intensity = sim.scan_values()
        sel = _cluster(ranges[start : end + 1], max(cluster, 1), self.model.dmin)
        if kind[1] == "S":
            payload = encode_array(np.minimum(sel, 4095), 2)
        elif kind[1] == "E":
            inten = _cluster(intensity[start : end + 1], max(cluster, 1), 0)
            pairs = np.stack([sel, inten], axis=1).ravel()
            payload = encode_array(pairs, 3)
        else:
            payload = encode_array(sel, 3)
        ts = scip2.encode_value(sim.timer_ms(sim.scan_start(k)), 4)
        return scip2.with_sum(ts) + scip2.data_lines(payload) + b"\n"

    # ---------------------------------------------------------------- requests

    def _handle(self, line: bytes, now: float) -> bytes:
        sim = self.sim
        if line == scip2.SCIP20:
            sim.scip11 = False
            return b"SCIP2.0\n0\n\n"
        if sim.scip11:
            return line + b"\nE\n\n"
        req = scip2.parse_request(line)
        cmd = req.command
        if req.error is None and cmd not in _SUPPORTED:
            req = scip2.Request(cmd, error="0E")
        if cmd in ("GE", "ME") and not self.model.intensity:
            return self._reply(line, "0E")
        if cmd == "RT" and not self.model.rt:
            return self._reply(line, "0E")
        if cmd[:1] == "%" and not self.model.state_commands:
            return self._reply(line, "0E")
        if req.error is not None:
            return self._reply(line, req.error)
        if self.adjust and cmd not in ("TM", "%ST"):
            return self._reply(line, "0E")
        if self.sleeping and cmd in ("QT", "BM", "MD", "MS", "ME", "RS", "RT", "RB"):
            self.sleeping = False  # woken up (the motor comes back to speed at once here)
        head, sep, string = line.partition(b";")
        handler = getattr(self, f"_cmd_{_HANDLER.get(cmd, cmd.lower())}")
        reply: bytes = handler(line, head, sep + string, head[2:], now)
        return reply

    def _reply(self, echo: bytes, code: str, body: bytes = b"") -> bytes:
        return echo + b"\n" + status(code) + body + b"\n"

    def _cmd_vv(self, line: bytes, *_: object) -> bytes:
        return self._reply(line, "00", info([f"{k}:{v}" for k, v in self.model.vv]))

    def _cmd_pp(self, line: bytes, *_: object) -> bytes:
        return self._reply(line, "00", info(self.model.pp()))

    def _cmd_ii(self, line: bytes, *_: object) -> bytes:
        mode = "Measuring by Normal Mode" if self.laser else "IDLE"
        lines = self.model.ii(laser=self.laser, mode=mode, time_ms=self.sim.timer_ms())
        return self._reply(line, "00", info(lines))

    def _cmd_bm(self, line: bytes, *_: object) -> bytes:
        if self.laser:
            return self._reply(line, "02")
        self.laser = True
        self.first_scan = self.sim.first_scan_from(self.sim.now())
        return self._reply(line, "00")

    def _cmd_qt(self, line: bytes, *_: object) -> bytes:
        if self.sim.ignore_qt and self.stream is not None:
            return b""  # fault injection: the stop is lost
        self.stream, self.laser = None, False
        return self._reply(line, "00")

    def _cmd_rs(self, line: bytes, *_: object) -> bytes:
        """RS/RT: laser off, streaming stopped, timer 0, normal sensitivity (hokuyolx's list;
        RS also resets motor speed and bit rate, which the simulator does not change)."""
        self.stream, self.laser, self.high_sensitivity = None, False, False
        self.sim.reset_timer()
        return self._reply(line, "00")

    _cmd_rt = _cmd_rs

    def _state_code(self) -> str:
        if self.adjust:
            return "002"
        if self.sleeping:
            return "005"
        if self.stream is not None:
            return "004"
        return "003" if self.laser else "000"

    def _cmd_state(self, line: bytes, *_: object) -> bytes:
        """%ST: the sensor's state as 3 digits (+ sum), valid in every state."""
        return self._reply(line, "00", scip2.with_sum(self._state_code().encode()))

    def _cmd_sleep(self, line: bytes, *_: object) -> bytes:
        """%SL: from standby or measuring: stop, laser off, motor stopped."""
        if self._state_code() not in ("000", "003", "004"):
            return self._reply(line, "10")
        self.stream, self.laser, self.sleeping = None, False, True
        return self._reply(line, "00")

    def _cmd_rb(self, line: bytes, head: bytes, string: bytes, params: bytes, now: float) -> bytes:
        if self._rb_at is None or now - self._rb_at > RB_WINDOW_S:
            self._rb_at = now
            return self._reply(line, "01")
        self._rb_at = None
        self.stream, self.laser, self.adjust = None, False, False
        self.high_sensitivity = self.sleeping = False
        self.sim.reboot()
        return self._reply(line, "00")

    def _cmd_tm(self, line: bytes, head: bytes, string: bytes, params: bytes, now: float) -> bytes:
        code = params.decode("latin-1")
        if code == "0":
            if self.adjust:
                return self._reply(line, "02")
            if self.stream is not None or self.sleeping:
                return self._reply(line, "10")
            self.adjust, self.laser = True, False
            return self._reply(line, "00")
        if code == "1":
            if not self.adjust:
                return self._reply(line, "04")
            t = scip2.encode_value(self.sim.timer_ms(), 4)
            return self._reply(line, "00", scip2.with_sum(t))
        if code == "2":
            if not self.adjust:
                return self._reply(line, "03")
            self.adjust = False
            return self._reply(line, "00")
        return self._reply(line, "01")

    def _cmd_ss(self, line: bytes, head: bytes, string: bytes, params: bytes, now: float) -> bytes:
        if not params.isdigit():
            return self._reply(line, "01")
        return self._reply(line, "0F" if self.tcp else "00")  # no bit rate on Ethernet

    def _cmd_cr(self, line: bytes, head: bytes, string: bytes, params: bytes, now: float) -> bytes:
        if not params.isdigit():
            return self._reply(line, "01")
        if self.model.name != "urg-04lx":
            return self._reply(line, "04")
        return self._reply(line, "00" if int(params) <= 10 or int(params) == 99 else "02")

    def _cmd_hs(self, line: bytes, head: bytes, string: bytes, params: bytes, now: float) -> bytes:
        if params not in (b"0", b"1"):
            return self._reply(line, "01")
        on = params == b"1"
        if on == self.high_sensitivity:
            return self._reply(line, "02")
        self.high_sensitivity = on
        return self._reply(line, "00")

    def _range_fields(self, params: bytes) -> tuple[str, tuple[int, int, int]]:
        """Status of the start/end/cluster fields ("" if valid) and their values."""
        for i, (a, b) in enumerate(((0, 4), (4, 8), (8, 10))):
            if not params[a:b].isdigit():
                return f"0{i + 1}", (0, 0, 0)
        start, end, cluster = int(params[0:4]), int(params[4:8]), int(params[8:10])
        if end > self.model.amax:
            return "04", (0, 0, 0)
        if end < start:
            return "05", (0, 0, 0)
        return "", (start, end, cluster)

    def _cmd_gd(self, line: bytes, head: bytes, string: bytes, params: bytes, now: float) -> bytes:
        code, (start, end, cluster) = self._range_fields(params)
        if code:
            return self._reply(line, code)
        if not self.laser:
            return self._reply(line, "10")
        kind = head[:2].decode()
        k = max(self.sim.latest_scan(), self.first_scan)  # measured with the laser on

        def build() -> bytes:
            return line + b"\n" + status("00") + self._data(kind, start, end, cluster, k)

        if k > self.sim.latest_scan():  # not complete yet: on_frame waits for it
            self._pending = (k, build)
            return b""
        return build()

    _cmd_gs = _cmd_ge = _cmd_gd

    def _cmd_md(self, line: bytes, head: bytes, string: bytes, params: bytes, now: float) -> bytes:
        code, (start, end, cluster) = self._range_fields(params)
        if code:
            return self._reply(line, code)
        if not params[10:11].isdigit():
            return self._reply(line, "06")
        if not params[11:13].isdigit():
            return self._reply(line, "07")
        count = int(params[11:13])
        self.laser = True
        self.first_scan = self.sim.first_scan_from(self.sim.now())  # begun after the command
        self.stream = Stream(
            kind=head[:2].decode(), head=head[:13], string=string, start=start, end=end,
            cluster=cluster, interval=int(params[10:11]), remaining=count or None,
            next_k=self.first_scan,
        )  # fmt: skip
        return self._reply(line, "00")

    _cmd_ms = _cmd_me = _cmd_md


def _cluster(values: np.ndarray, c: int, dmin: int) -> np.ndarray:
    """Groups of ``c`` steps -> one value each: the minimum of the group's ranges (codes
    below ``dmin`` ignored); a group of codes only gives its first code (SPEC p.10)."""
    if c <= 1:
        return values
    n = len(values)
    groups = -(-n // c)
    padded = np.full(groups * c, -1, dtype=np.int64)
    padded[:n] = values
    g = padded.reshape(groups, c)
    valid = g >= dmin
    best = np.where(valid, g, np.iinfo(np.int64).max).min(axis=1)
    out: np.ndarray = np.where(valid.any(axis=1), best, g[:, 0])
    return out


def encode_array(values: np.ndarray, width: int) -> bytes:
    """``values`` (each 0..2**(6*width)-1) in the SCIP ``width``-char encoding, all at once
    (the simulator's output path; :func:`robocli.protocols.scip2.encode_values` is the
    reference it is tested against)."""
    v = np.asarray(values, dtype=np.int64)
    shifts = np.arange(width - 1, -1, -1, dtype=np.int64) * 6
    chars = ((v[:, None] >> shifts) & 0x3F) + 0x30
    return chars.astype(np.uint8).tobytes()
