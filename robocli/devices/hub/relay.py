"""A hub's serial port on a local pseudo-terminal: :class:`PtyRelay`.

Any program opens :attr:`PtyRelay.path` as if the robot were plugged into this machine.
Bytes go both ways as they come, through a :class:`~robocli.devices.hub.serial.VirtualSerial`.
The line settings the program sets on the pty (``tcsetattr``: baud rate, byte size, parity,
stop bits) are read back before every byte it writes and sent to the hub first, so they
reach the hub's port before the bytes that follow them. (A rate set through Linux's
``BOTHER`` custom-speed call is not seen on a pty: it keeps the last standard rate.)

POSIX only (pseudo-terminals).
"""

from __future__ import annotations

import errno
import logging
import os
import select
import threading
import time
from collections.abc import Callable
from typing import Any

from robocli.devices.hub.serial import LineSettings, VirtualSerial
from robocli.devices.hub.zenoh_serial import ZenohSerialLine
from robocli.errors import ConnectionLost, InvalidArgument

__all__ = ["PtyRelay", "settings_of"]

log = logging.getLogger("robocli.devices.hub.relay")

POLL_S = 0.05  #: how often the pty's settings are looked at while nothing flows
READ_SIZE = 4096
WRITE_DEADLINE_S = 1.0
"""Bytes from the hub wait this long for the program to make room on the pty, then are
dropped (and counted), as on a serial line nobody reads."""
_CMSPAR = 0o10000000000  # Linux: mark/space parity (termios does not name it)


def _bauds(termios: Any) -> dict[int, int]:
    rates = [50, 75, 110, 134, 150, 200, 300, 600, 1200, 1800, 2400, 4800, 9600, 19200, 38400,
             57600, 115200, 230400, 460800, 500000, 576000, 921600, 1000000, 1152000, 1500000,
             2000000, 2500000, 3000000, 3500000, 4000000]  # fmt: skip
    return {getattr(termios, f"B{r}"): r for r in rates if hasattr(termios, f"B{r}")}


def settings_of(attrs: list[Any], last: LineSettings) -> LineSettings:
    """The line settings a ``termios.tcgetattr`` list says (a speed it does not name keeps
    ``last``'s)."""
    import termios

    cflag, speed = attrs[2], attrs[5]
    sizes = {termios.CS5: 5, termios.CS6: 6, termios.CS7: 7, termios.CS8: 8}
    parity = "N"
    if cflag & termios.PARENB:
        odd = bool(cflag & termios.PARODD)
        parity = ("M" if odd else "S") if cflag & _CMSPAR else ("O" if odd else "E")
    return LineSettings(
        baudrate=_bauds(termios).get(speed, last["baudrate"]),
        bytesize=sizes.get(cflag & termios.CSIZE, 8),
        parity=parity,
        stopbits=2 if cflag & termios.CSTOPB else 1,
    )


class PtyRelay:
    """A local pty relayed to the serial ``port`` of ``hub`` (see the module docstring).

    :meth:`open` creates the pty (:attr:`path`) and opens the hub's port at the pty's
    initial settings (``baudrate``, 8N1; the program's own come before its first byte);
    :meth:`run` relays until ``stop`` is set or the line ends (its error is raised).
    ``on_event(kind, text)``: the line's ``lost``, ``resumed``, ``ended``.
    ``VirtualSerial`` keywords (``token``, ``timeout``, ``resume``) pass through.
    ``zenoh``: a Zenoh configuration; ``hub`` is then the hub's name on Zenoh and the line a
    :class:`~robocli.devices.hub.zenoh_serial.ZenohSerialLine` (``token``, ``timeout``).
    """

    def __init__(
        self, hub: str, port: str, *, baudrate: int = 9600,
        on_event: Callable[[str, str], None] | None = None, zenoh: str | None = None,
        **line: Any,
    ) -> None:  # fmt: skip
        if os.name != "posix":
            raise InvalidArgument("a local pty needs a POSIX system (Linux, macOS)")
        self.hub, self.port = hub, port
        self._baudrate = baudrate
        self._on_event = on_event
        self._line_kw = line
        self._zenoh = zenoh
        self.master = self.slave = -1
        self.path = ""
        self.line: VirtualSerial | ZenohSerialLine | None = None
        self.dropped = 0  #: bytes from the hub the program did not take in time
        self._attrs: list[Any] | None = None

    def open(self) -> PtyRelay:
        """Create the pty and open the hub's port; returns self. Errors of
        :meth:`VirtualSerial.open <robocli.devices.hub.serial.VirtualSerial.open>`."""
        import pty
        import termios
        import tty

        self.master, self.slave = pty.openpty()
        try:
            tty.setraw(self.slave)  # bytes pass as they are until the program sets its own
            attrs = termios.tcgetattr(self.slave)
            speed = {v: k for k, v in _bauds(termios).items()}.get(self._baudrate)
            if speed is not None:
                attrs[4] = attrs[5] = speed
                termios.tcsetattr(self.slave, termios.TCSANOW, attrs)
            self._attrs = termios.tcgetattr(self.slave)
            os.set_blocking(self.master, False)
            self.path = os.ttyname(self.slave)
            settings = settings_of(self._attrs, LineSettings(self._baudrate))
            if self._zenoh is not None:
                self.line = ZenohSerialLine.open(
                    self.hub, self.port, zenoh=self._zenoh, **settings, on_data=self._to_pty,
                    on_event=self._on_event, **self._line_kw,
                )  # fmt: skip
            else:
                self.line = VirtualSerial.open(
                    self.hub, self.port, **settings, on_data=self._to_pty,
                    on_event=self._on_event, **self._line_kw,
                )  # fmt: skip
        except BaseException:
            self.close()
            raise
        return self

    def _to_pty(self, data: bytes) -> None:
        """Bytes from the hub, written to the program's side (the line's reader thread)."""
        view, end = memoryview(data), time.monotonic() + WRITE_DEADLINE_S
        while view:
            try:
                n = os.write(self.master, view)
                view = view[n:]
                continue
            except BlockingIOError:
                pass
            except OSError as exc:
                log.info("pty %s: write failed: %s", self.path, exc)
                break
            left = end - time.monotonic()
            if left <= 0 or not select.select([], [self.master], [], left)[1]:
                break
        if view:
            self.dropped += len(view)
            log.warning("pty %s: the program did not read: %d bytes dropped", self.path,
                        len(view))  # fmt: skip

    def _sync_settings(self) -> None:
        """Send the pty's settings to the hub if the program changed them."""
        import termios

        attrs = termios.tcgetattr(self.slave)
        if attrs == self._attrs:
            return
        self._attrs = attrs
        line = self.line
        assert line is not None
        try:
            line.configure(**settings_of(attrs, line.settings))
        except InvalidArgument as exc:
            log.warning("pty %s: settings not sent: %s", self.path, exc)

    def run(self, stop: threading.Event) -> None:
        """Relay until ``stop`` is set; raises the line's error if it ends first."""
        line = self.line
        assert line is not None
        while not stop.is_set():
            if line.ended is not None:
                raise line.ended
            if not line.connected:  # the hub is away: the program's bytes wait in the pty
                stop.wait(POLL_S)
                continue
            ready = select.select([self.master], [], [], POLL_S)[0]
            try:
                self._sync_settings()
                if not ready:
                    continue
                try:
                    data = os.read(self.master, READ_SIZE)
                except BlockingIOError:
                    continue
                except OSError as exc:
                    if exc.errno != errno.EIO:
                        raise
                    stop.wait(POLL_S)  # no program holds the pty just now
                    continue
                if data:
                    line.write(data)
            except ConnectionLost:
                if line.ended is not None:
                    raise line.ended from None
                # lost between the check and the write: the watcher reconnects (the bytes
                # of this read are lost with the link, as on an unplugged cable)

    def close(self) -> None:
        """Close the hub's port and the pty (idempotent)."""
        if self.line is not None:
            self.line.close()
        for fd in (self.master, self.slave):
            if fd >= 0:
                try:
                    os.close(fd)
                except OSError:
                    pass
        self.master = self.slave = -1

    def __enter__(self) -> PtyRelay:
        return self if self.line is not None else self.open()

    def __exit__(self, *exc: object) -> None:
        self.close()
