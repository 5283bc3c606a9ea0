"""Real sources: this machine's system info (/proc), a gpsd daemon (JSON), serial ports.

* :class:`SysinfoSource`: CPU load split by state (from ``/proc/stat`` deltas, %), load
  averages, memory (kB: used, free, buffers) and the CPU temperature where a thermal zone
  exists (NaN otherwise): the ros4mat ``msgComputer`` record.
* :class:`GpsdSource`: a client of gpsd's JSON protocol (``?WATCH``); each TPV report becomes a
  ``msgGps`` record stamped with its arrival on the hub's clock. Reconnects with a backoff;
  lines are bounded.
* :class:`SerialPorts`: the remote serial port of SERIAL_CMD (pyserial), restricted to the
  ports named on the server's command line.
"""

from __future__ import annotations

import collections
import json
import logging
import math
import socket
import threading
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from robocli.errors import DeviceError
from robocli.hub_server.sources.base import Batch, PeriodicSource, Source, rate_param
from robocli.protocols.ros4mat import ComputerState, GpsState, SerialStatus, record_dtype
from robocli.transports import parse_address

__all__ = ["GpsdSource", "SerialPorts", "SysinfoSource", "parse_host_port"]

log = logging.getLogger("robocli.hub_server")

PROC = Path("/proc")
MAX_LINE = 64 * 1024  #: longest gpsd JSON line accepted
MAX_QUEUED = 1024  #: gpsd fixes kept between polls
MAX_SERIAL_READ = 4096  #: bytes one SERIAL_CMD may read
MAX_SERIAL_WAIT_S = 5.0  #: longest read timeout honoured (ros4mat's receive timeout)
SERIAL_QUEUE_S = 3.0
"""A SERIAL_CMD waits this long for the commands ahead of it, then is refused "busy" (an
answer well within the client's patience, rather than none)."""


def parse_host_port(text: str, default_port: int) -> tuple[str, int]:
    """``"HOST[:PORT]"`` -> (host, port) by :func:`robocli.transports.parse_address`;
    :class:`InvalidArgument` if malformed."""
    return parse_address(text, default_port, what="gpsd")


class SysinfoSource(PeriodicSource):
    """This machine's load, memory and temperature from /proc and /sys (Linux)."""

    name = "sysinfo"
    simulated = False
    MAX_RATE = 50.0

    def __init__(self, proc: Path = PROC) -> None:
        self._proc = proc
        self._last: list[int] | None = None
        self._last_load: list[float] = [math.nan] * 7  # the last split measured
        super().__init__()

    def configure(self, params: Mapping[str, Any]) -> None:
        self.rate = rate_param(params, "freq_acquisition", 1.0, self.MAX_RATE)
        self.batch_rate = self.rate
        self.params = {}

    def dtype(self) -> np.dtype[Any]:
        return record_dtype("computer")

    def start(self, t0: float) -> None:
        super().start(t0)
        self._last = self._cpu_times()

    def _cpu_times(self) -> list[int] | None:
        try:
            first = (self._proc / "stat").read_text().splitlines()[0].split()
        except (OSError, IndexError):
            return None
        # user nice system idle iowait irq softirq
        return [int(v) for v in first[1:8]] if first[0] == "cpu" and len(first) >= 8 else None

    def cpu_load(self) -> list[float]:
        """Percent of CPU time since the last call: user, sys, nice, idle, iowait, hirq, sirq."""
        now = self._cpu_times()
        last, self._last = self._last, now
        if now is None or last is None:
            return [math.nan] * 7
        d = [a - b for a, b in zip(now, last, strict=True)]
        total = sum(d)
        if total <= 0:  # no clock tick (10 ms) since the last call: keep measuring from `last`
            self._last = last
            return list(self._last_load)
        user, nice, system, idle, iowait, irq, softirq = (100.0 * v / total for v in d)
        self._last_load = [user, system, nice, idle, iowait, irq, softirq]
        return list(self._last_load)

    def load_average(self) -> list[float]:
        try:
            return [float(v) for v in (self._proc / "loadavg").read_text().split()[:3]]
        except (OSError, ValueError):
            return [math.nan] * 3

    def memory(self) -> list[int]:
        """kB used, free, buffers."""
        info: dict[str, int] = {}
        try:
            for line in (self._proc / "meminfo").read_text().splitlines():
                key, _, rest = line.partition(":")
                info[key] = int(rest.split()[0])
        except (OSError, ValueError, IndexError):
            return [0, 0, 0]
        total, free = info.get("MemTotal", 0), info.get("MemFree", 0)
        clip = 0xFFFFFFFF
        return [min(total - free, clip), min(free, clip), min(info.get("Buffers", 0), clip)]

    @staticmethod
    def temperature() -> float:
        """CPU temperature (deg C) from the first thermal zone, NaN where there is none."""
        for zone in sorted(Path("/sys/class/thermal").glob("thermal_zone*/temp")):
            try:
                return int(zone.read_text().strip()) / 1000.0
            except (OSError, ValueError):
                continue
        return math.nan

    def sample(self, t: npt.NDArray[np.float64]) -> npt.NDArray[Any]:
        rec = np.zeros(len(t), dtype=self.dtype())
        rec["t"] = t
        load = self.cpu_load()
        rec["state"] = ComputerState.ERROR if math.isnan(load[0]) else ComputerState.OK
        rec["cpu_temperature"] = self.temperature()
        rec["unix_load"] = self.load_average()
        rec["cpu_load"] = load
        rec["memory"] = self.memory()
        return rec


# ============================================================================ gpsd


class GpsdSource(Source):
    """GPS fixes from a gpsd daemon at ``host:port`` (JSON protocol, ``?WATCH``)."""

    name = "gps"
    simulated = False
    RETRY_S = 1.0

    def __init__(self, host: str, port: int = 2947) -> None:
        self.host, self.port = host, port
        self._queue: collections.deque[tuple[float, tuple[Any, ...]]] = collections.deque(
            maxlen=MAX_QUEUED
        )
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._sock: socket.socket | None = None
        self.reports = 0  #: TPV reports received
        self.bad_lines = 0  #: lines that were not JSON or too long
        super().__init__()

    def configure(self, params: Mapping[str, Any]) -> None:
        self.rate = rate_param(params, "freq_acquisition", 1.0, 50.0)  # gpsd sets the real rate
        self.batch_rate = 10.0
        self.params = {"gpsd": f"{self.host}:{self.port}"}

    def dtype(self) -> np.dtype[Any]:
        return record_dtype("gps")

    def start(self, t0: float) -> None:
        if self._thread is None:
            self._stop.clear()
            self._thread = threading.Thread(target=self._run, name="hub-gpsd", daemon=True)
            self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        sock = self._sock
        if sock is not None:
            try:
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass  # not connected
        if self._thread is not None:
            self._thread.join(2.0)
            self._thread = None

    def poll(self, now: float) -> Batch:
        items = []
        while self._queue:
            items.append(self._queue.popleft())
        if not items:
            return self.empty()
        rec = np.zeros(len(items), dtype=self.dtype())
        t = np.array([ti for ti, _ in items], dtype=np.float64)
        fields = ("state", "latitude", "longitude", "altitude", "speed", "track", "climb")
        for name, column in zip(fields, zip(*(v for _, v in items), strict=True), strict=True):
            rec[name] = column
        rec["t"] = t
        return t, rec

    def feed_line(self, line: bytes, now: float) -> None:
        """Handle one gpsd JSON line (TPV reports become fixes; the rest is ignored)."""
        try:
            msg = json.loads(line)
        except (ValueError, RecursionError):  # not JSON, or nested too deeply
            self.bad_lines += 1
            return
        if not isinstance(msg, dict) or msg.get("class") != "TPV":
            return
        mode = int(msg.get("mode", 0) or 0)
        state = {2: GpsState.FIX_2D, 3: GpsState.FIX_3D}.get(mode, GpsState.NO_FIX)

        def num(key: str, *alts: str) -> float:
            for k in (key, *alts):
                v = msg.get(k)
                if isinstance(v, (int, float)):
                    return float(v)
            return math.nan

        self.reports += 1
        self._queue.append(
            (
                now,
                (
                    int(state),
                    num("lat"),
                    num("lon"),
                    num("altMSL", "alt", "altHAE"),
                    num("speed"),
                    num("track"),
                    num("climb"),
                ),
            )
        )

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                self._session()
            except OSError as exc:
                log.info("gpsd %s:%d: %s; retrying", self.host, self.port, exc)
            self._stop.wait(self.RETRY_S)

    def _session(self) -> None:
        with socket.create_connection((self.host, self.port), timeout=5.0) as sock:
            self._sock = sock
            sock.sendall(b'?WATCH={"enable":true,"json":true};\n')  # within the 5 s timeout
            sock.settimeout(None)  # then block on reports; stop() shuts the socket down
            buf = bytearray()
            while not self._stop.is_set():
                data = sock.recv(65536)
                if not data:
                    return
                buf += data
                while (nl := buf.find(b"\n")) >= 0:
                    line = bytes(buf[:nl])
                    del buf[: nl + 1]
                    self.feed_line(line, self.clock())
                if len(buf) > MAX_LINE:
                    self.bad_lines += 1
                    buf.clear()


# ============================================================================ serial


class SerialPorts:
    """SERIAL_CMD's remote serial ports: only ``allowed`` (names as given on the command
    line); each opened on first use with the request's settings, kept open unless the
    request says ``close_after``."""

    def __init__(self, allowed: tuple[str, ...] | list[str]) -> None:
        self.allowed = tuple(allowed)
        self._open: dict[str, Any] = {}
        self._streamed: dict[str, Any] = {}  # claimed by a stream (robocli.hub_server.serial)
        self._lock = threading.Lock()

    @property
    def open_ports(self) -> list[str]:
        """The ports open now."""
        with self._lock:
            return list(self._open)

    def command(self, req: Mapping[str, Any]) -> tuple[int, bytes]:
        """Run one SERIAL_CMD (decoded ``SerialCmdRequest``): (status, bytes read)."""
        cmd = req["cmd"]
        name = bytes(req["port"]).split(b"\0", 1)[0].decode("ascii", "replace")
        self.check(name)
        if not self._lock.acquire(timeout=SERIAL_QUEUE_S):
            raise DeviceError(
                f"serial port {name!r} busy: other clients' commands held the hub's serial "
                f"ports for {SERIAL_QUEUE_S:g} s; retry"
            )
        try:
            if name in self._streamed:
                raise DeviceError(f"serial port {name!r} busy: a client streams it")
            try:
                port = self._port(name, cmd)
            except (OSError, ValueError) as exc:
                log.info("serial %s: cannot open: %s", name, exc)
                return SerialStatus.NO_OPEN, b""
            try:
                return self._exchange(port, cmd, bytes(req["data"]))
            except (OSError, ValueError) as exc:
                log.info("serial %s: %s", name, exc)
                self._close(name)
                return SerialStatus.BAD_SELECT, b""
            finally:
                if cmd["close_after"]:
                    self._close(name)
        finally:
            self._lock.release()

    def check(self, name: str) -> None:
        """:class:`DeviceError` unless ``name`` is on the allow-list."""
        if name not in self.allowed:
            raise DeviceError(f"serial port {name!r} is not served by this hub")

    def claim(self, name: str, settings: Mapping[str, Any]) -> Any:
        """Open ``name`` (allowed, not streamed yet) with pyserial ``settings`` for a stream
        that holds it alone until :meth:`release`. :class:`DeviceError` when it is not on the
        allow-list, streamed already, busy past the queue time or cannot be opened."""
        self.check(name)
        if not self._lock.acquire(timeout=SERIAL_QUEUE_S):
            raise DeviceError(f"serial port {name!r} busy: other clients' commands; retry")
        try:
            if name in self._streamed:
                raise DeviceError(f"serial port {name!r} busy: another client streams it")
            self._close(name)  # SERIAL_CMD's handle: the stream opens its own
            try:
                port = _open_port(name, settings)
            except PORT_ERRORS as exc:
                raise DeviceError(f"serial port {name!r} cannot be opened on the hub: "
                                  f"{exc}") from None  # fmt: skip
            self._streamed[name] = port
            return port
        finally:
            self._lock.release()

    def release(self, name: str) -> None:
        """Close the port a stream claimed (idempotent)."""
        with self._lock:
            port = self._streamed.pop(name, None)
        if port is not None:
            port.close()

    def _port(self, name: str, cmd: Mapping[str, Any]) -> Any:
        import serial

        port = self._open.get(name)
        settings = {
            "baudrate": int(cmd["speed"]) or 9600,
            "parity": serial.PARITY_EVEN if cmd["parity"] else serial.PARITY_NONE,
            "stopbits": serial.STOPBITS_TWO if cmd["stop_bits"] == 2 else serial.STOPBITS_ONE,
        }
        if port is None:
            port = _open_port(name, settings)
            self._open[name] = port
        else:
            port.apply_settings(settings)
        return port

    @staticmethod
    def _exchange(port: Any, cmd: Mapping[str, Any], data: bytes) -> tuple[int, bytes]:
        want = min(int(cmd["read_length"]), MAX_SERIAL_READ)
        if not data and not want:
            port.reset_input_buffer()
            port.reset_output_buffer()
            return SerialStatus.OK, b""
        if data:
            port.write(data)
            port.flush()
        wait = max(0, cmd["read_timeout_sec"]) + cmd["read_timeout_usec"] / 1e6
        end = time.monotonic() + min(wait, MAX_SERIAL_WAIT_S)
        got = bytearray()
        while len(got) < want:
            left = end - time.monotonic()
            if left <= 0:
                break
            port.timeout = min(left, 0.05)
            got += port.read(want - len(got))
        return (SerialStatus.OK if len(got) >= want else SerialStatus.TIMEOUT), bytes(got)

    def _close(self, name: str) -> None:
        port = self._open.pop(name, None)
        if port is not None:
            port.close()

    def close(self) -> None:
        """Close every open port (the streams' too)."""
        with self._lock:
            for name in list(self._open):
                self._close(name)
            streamed, self._streamed = list(self._streamed.values()), {}
        for port in streamed:
            port.close()


try:
    from termios import error as _TermiosError
except ImportError:  # not POSIX: pyserial raises its own errors only
    _TermiosError = OSError  # type: ignore[misc,assignment]
PORT_ERRORS = (OSError, ValueError, _TermiosError)
"""What pyserial raises when a port cannot open, refuses settings or fails (its
SerialException is an OSError; termios.error escapes it on POSIX)."""


def _open_port(name: str, settings: Mapping[str, Any]) -> Any:
    """A pyserial port (a device path or any pyserial URL) with ``settings``; reads do not
    block, writes have a 1 s deadline (a stream sets its own)."""
    import serial

    return serial.serial_for_url(name, timeout=0, write_timeout=1.0, **settings)
