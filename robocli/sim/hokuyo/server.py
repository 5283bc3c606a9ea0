"""Built-in Hokuyo scanner simulator: SCIP 2.0 over a pty (USB CDC-ACM) or TCP (10940).

``HokuyoSim(model)`` serves one client at a time (a second TCP client is refused, as the
sensor has one measurement connection). The scanner sits at ``pose`` (default: the world's
start) in a :class:`~robocli.sim.world.World` (default: the Pioneer simulator's room) and
ray-casts every step with :func:`robocli.sim.laser.cast`; ranges are the exact distances
rounded to whole millimetres. Intensities (GE/ME) are a smooth function of range.

Time: ``time_scale`` simulated seconds per wall second. Scan ``k`` is measured over
``[k * P, (k + 1) * P)`` simulated seconds (``P = 60 / SCAN``); its timestamp is the 24-bit
millisecond timer at its start (``timer_start_ms`` from boot, RS/RT/reboot set it to 0), so
a test can start near the wrap; ``drift_ppm`` makes that timer run fast (or slow) against
simulated time, as a sensor's crystal does against the host's clock. A ticker at the scan
period sends each streaming session the frames that are due (a TCP client that does not
read is dropped by the serving layer; on a pty whose reader leaves its buffer full, frames
are dropped whole, and what the line cannot take is lost, as on a serial line).
A TCP client that disconnects leaves the sensor idle; a pty session lives as long as the
simulator (a client that dies while MD streams finds it still streaming).
"""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import numpy.typing as npt

from robocli.closing import Closing
from robocli.errors import InvalidArgument
from robocli.protocols.scip2.framing import RequestFramer
from robocli.serving.server import SIM_HANDSHAKE_S, Link, Server
from robocli.serving.ticker import Ticker
from robocli.sim.hokuyo.model import MODELS, HokuyoModel, measure
from robocli.sim.hokuyo.session import ScipSession
from robocli.sim.world import World

__all__ = ["HokuyoSim"]

IntArray = npt.NDArray[np.int64]
BYTE_TIMEOUT_S = 5.0  #: a request line left unterminated this long is dropped
SEND_TIMEOUT_S = 2.0  #: a TCP client leaving frames unread this long is dropped


class HokuyoSim(Closing):
    """A simulated scanner; :meth:`serve_tcp` or :meth:`serve_pty`, then :meth:`close`."""

    def __init__(
        self,
        model: str | HokuyoModel = "utm-30lx",
        *,
        world: World | None = None,
        pose: tuple[float, float, float] | None = None,
        time_scale: float = 1.0,
        scip11: bool | None = None,
        timer_start_ms: int = 0,
        drift_ppm: float = 0.0,
        handshake_s: float = SIM_HANDSHAKE_S,
    ) -> None:
        if isinstance(model, str):
            if model not in MODELS:
                raise InvalidArgument(f"unknown laser model {model!r}; known: {', '.join(MODELS)}")
            model = MODELS[model]
        if not time_scale > 0:
            raise InvalidArgument("time_scale must be > 0")
        if not handshake_s > 0:
            raise InvalidArgument("handshake_s must be > 0")
        self.handshake_s = handshake_s
        self.model = model
        self.world = world if world is not None else World.default()
        self.time_scale = time_scale
        self.drift = 1.0 + drift_ppm * 1e-6
        """Sensor seconds per simulated second: a crystal off by ``drift_ppm``."""
        self._boot_scip11 = model.scip11 if scip11 is None else scip11
        self.scip11 = self._boot_scip11
        self._lock = threading.Lock()
        self._t0 = time.monotonic()
        # the simulated time at which the timer read 0
        self._timer_zero = -timer_start_ms / 1000.0 / self.drift
        self._sessions: list[ScipSession] = []
        self._pose = pose if pose is not None else self.world.start
        self._values = self._measure(self._pose)
        self._server: Server | None = None
        self._tcp = False
        self._ticker = Ticker(model.period / time_scale, self._tick, f"hokuyo-{model.name}")
        self.mute = False
        """Fault injection: answer nothing and stream nothing (a sensor that hung)."""
        self.ignore_qt = False
        """Fault injection: a QT while streaming gets no reply and the stream goes on (a
        sensor whose stop was lost)."""
        self._closed = threading.Event()

    # ---------------------------------------------------------------- time and scans

    def now(self) -> float:
        """Simulated seconds since the simulator started."""
        return (time.monotonic() - self._t0) * self.time_scale

    def timer_ms(self, t: float | None = None) -> int:
        """The sensor's 24-bit millisecond timer at simulated time ``t`` (default: now)."""
        t = self.now() if t is None else t
        return math.floor((t - self._timer_zero) * self.drift * 1000.0 + 1e-6) & 0xFFFFFF

    def scan_start(self, k: int) -> float:
        """Simulated time at which scan ``k`` starts."""
        return k * self.model.period

    def latest_scan(self) -> int:
        """Index of the latest complete scan (-1 before the first one completes)."""
        return math.floor(self.now() / self.model.period + 1e-9) - 1

    def first_scan_from(self, t: float) -> int:
        """Index of the first scan that starts at or after simulated time ``t``."""
        return math.ceil(t / self.model.period - 1e-9)

    def wait_scan(self, k: int) -> None:
        """Wait until scan ``k`` is complete (the scan clock; at most its period from its
        start), or the simulator closes."""
        done = self.scan_start(k + 1)
        while (left := done - self.now()) > 0 and not self._closed.is_set():
            self._closed.wait(left / self.time_scale + 1e-4)

    def reset_timer(self) -> None:
        """RS/RT: the timer reads 0 now (scans begun before it are never sent after it)."""
        self._timer_zero = self.now()

    def reboot(self) -> None:
        """RB: timer at 0, back to the protocol the model boots in."""
        self.reset_timer()
        self.scip11 = self._boot_scip11

    @property
    def pose(self) -> tuple[float, float, float]:
        return self._pose

    def set_pose(self, pose: tuple[float, float, float]) -> None:
        """Move the scanner (x, y m; th rad): later scans see the world from there."""
        values = self._measure(pose)
        with self._lock:
            self._pose, self._values = pose, values

    def scan_values(self) -> tuple[IntArray, IntArray]:
        """Wire values of steps 0..AMAX (ranges mm / codes) and their intensities."""
        with self._lock:
            return self._values

    def _measure(self, pose: tuple[float, float, float]) -> tuple[IntArray, IntArray]:
        m = self.model
        ranges = measure(m, self.world, pose, last_step=m.amax)
        hit = ranges >= m.dmin
        inten = np.where(hit, np.maximum(100, 12000 - ranges // 4), 0).astype(np.int64)
        ranges.setflags(write=False)
        inten.setflags(write=False)
        return ranges, inten

    def inject(self, data: bytes) -> int:
        """Fault injection: send raw ``data`` on every link now (garbage, a corrupted or
        truncated frame); how many links took it."""
        links = self._server.links() if self._server is not None else []
        return sum(link.send(data) for link in links)

    def _tick(self, now: float) -> None:
        if self.mute:
            return
        k = self.latest_scan()
        with self._lock:
            sessions = list(self._sessions)
        for s in sessions:
            s.on_scans(k)

    # ---------------------------------------------------------------- serving

    def _session(self, link: Link) -> ScipSession:
        s = ScipSession(self, link, tcp=self._tcp)
        with self._lock:
            self._sessions.append(s)
        return s

    def detach(self, session: ScipSession) -> None:
        with self._lock:
            if session in self._sessions:
                self._sessions.remove(session)

    def _serve(self, tcp: bool) -> Server:
        if self._server is not None:
            raise RuntimeError("this simulator already serves")
        self._tcp = tcp
        self._server = Server(
            self._session, protocol="scip", max_clients=1, framer=RequestFramer,
            byte_timeout=BYTE_TIMEOUT_S, send_timeout=SEND_TIMEOUT_S, max_backlog=1 << 20,
            name=f"hokuyo-{self.model.name}",
            busy_reason="laser busy: another client holds it",
            handshake_timeout=self.handshake_s,
        )  # fmt: skip
        self._t0 = time.monotonic()
        self._ticker.start()
        return self._server

    def serve_tcp(self, host: str = "127.0.0.1", port: int = 0) -> str:
        """Listen on ``host:port`` (0: ephemeral); ``tcp://host:port``."""
        return self._serve(True).serve_tcp(host, port)

    def serve_pty(self) -> str:
        """Serve on a new pseudo-terminal; its device path."""
        return self._serve(False).serve_pty()

    @property
    def url(self) -> str | None:
        return self._server.url if self._server else None

    @property
    def pty_path(self) -> str | None:
        return self._server.pty_path if self._server else None

    @property
    def server(self) -> Server | None:
        return self._server

    def sessions(self) -> list[ScipSession]:
        with self._lock:
            return list(self._sessions)

    def close(self) -> None:
        """Stop the scan clock and every link (idempotent)."""
        self._closed.set()
        self._ticker.close()
        if self._server is not None:
            self._server.close()
