"""``robocli://HOST[:PORT]/PATH[?baudrate=B&token=T&token_file=F&resume=S]``: a hub's serial
port as a pyserial port, for ``serial.serial_for_url`` (register the handler first:
:func:`robocli.devices.hub.serial_url.register`).

``PATH`` is the port's name on the hub (``/dev/ttyUSB0``: the URL's path as is). The
token comes from ``token=`` (the text of the hub's token file), else the file named by
``token_file=``, else the file named by ``$ROBOCLI_HUB_TOKEN_FILE``, else none (a hub
without a token). Line settings are pyserial's (``baudrate`` also in the URL): changed on an
open port, they go to the hub's port. A :class:`~robocli.devices.hub.serial.VirtualSerial`
does the work; its errors surface as ``serial.SerialException``.
"""

from __future__ import annotations

import os
import time
import urllib.parse
from pathlib import Path
from typing import Any

from serial.serialutil import PortNotOpenError, SerialBase, SerialException

from robocli.devices.hub.serial import VirtualSerial
from robocli.errors import RobocliError

__all__ = ["TOKEN_FILE_ENV", "Serial", "parse_url"]

TOKEN_FILE_ENV = "ROBOCLI_HUB_TOKEN_FILE"
MAX_TOKEN_FILE = 8192


def parse_url(url: str) -> tuple[str, str, dict[str, str]]:
    """(``HOST:PORT``, the hub's port name, the query's options) of a ``robocli://`` URL;
    ``SerialException`` for another scheme, no path or an unknown option."""
    parts = urllib.parse.urlsplit(url)
    if parts.scheme != "robocli" or not parts.netloc or not parts.path.strip("/"):
        raise SerialException(f"expected robocli://HOST[:PORT]/PORT-ON-HUB[?baudrate=...]: "
                              f"{url!r}")  # fmt: skip
    options = {k: v[-1] for k, v in urllib.parse.parse_qs(parts.query, True).items()}
    unknown = set(options) - {"baudrate", "token", "token_file", "resume"}
    if unknown:
        raise SerialException(f"{url!r}: unknown option(s) {', '.join(sorted(unknown))}")
    return parts.netloc, urllib.parse.unquote(parts.path), options


def _token(options: dict[str, str]) -> bytes | None:
    if options.get("token"):
        return options["token"].encode()
    path = options.get("token_file") or os.environ.get(TOKEN_FILE_ENV)
    if not path:
        return None
    try:
        with Path(path).open("rb") as f:
            return f.read(MAX_TOKEN_FILE).strip() or None
    except OSError as exc:
        raise SerialException(f"cannot read the hub's token file {path}: {exc}") from None


class Serial(SerialBase):  # type: ignore[misc]
    """A hub's serial port (see the module docstring)."""

    is_open: bool

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self._line: VirtualSerial | None = None
        super().__init__(*args, **kwargs)

    def open(self) -> None:
        if self.is_open:
            raise SerialException("Port is already open.")
        if self._port is None:
            raise SerialException("Port must be configured before it can be used.")
        hub, name, options = parse_url(self.portstr)
        if "baudrate" in options:
            self._baudrate = int(options["baudrate"])
        extra: dict[str, Any] = {}
        if "resume" in options:
            extra["resume"] = float(options["resume"])
        try:
            self._line = VirtualSerial.open(
                hub, name, baudrate=self._baudrate, bytesize=self._bytesize,
                parity=self._parity, stopbits=self._stopbits, token=_token(options), **extra,
            )  # fmt: skip
        except RobocliError as exc:
            raise SerialException(str(exc)) from exc
        self.is_open = True

    def _reconfigure_port(self) -> None:
        if self._line is not None:
            try:
                self._line.configure(baudrate=self._baudrate, bytesize=self._bytesize,
                                     parity=self._parity, stopbits=self._stopbits)  # fmt: skip
            except (RobocliError, ValueError) as exc:
                raise SerialException(str(exc)) from exc

    def close(self) -> None:
        if self._line is not None:
            self._line.close()
            self._line = None
        self.is_open = False

    def _live(self) -> VirtualSerial:
        if not self.is_open or self._line is None:
            raise PortNotOpenError()
        return self._line

    @property
    def in_waiting(self) -> int:
        return self._live().in_waiting

    def read(self, size: int = 1) -> bytes:
        """pyserial's semantics: ``timeout`` None waits for ``size`` bytes, 0 takes what is
        there, else waits at most ``timeout`` s in all."""
        line = self._live()
        end = None if self._timeout is None else time.monotonic() + self._timeout
        data = bytearray()
        try:
            while len(data) < size:
                left = None if end is None else max(0.0, end - time.monotonic())
                piece = line.read(size - len(data), timeout=left)
                data += piece
                if not piece and left is not None and left <= 0:
                    break
                if not piece and self._timeout == 0:
                    break
        except RobocliError as exc:
            raise SerialException(str(exc)) from exc
        return bytes(data)

    def write(self, data: bytes | bytearray | memoryview) -> int:
        try:
            return self._live().write(bytes(data))
        except RobocliError as exc:
            raise SerialException(str(exc)) from exc

    def flush(self) -> None:
        """Every write has gone to the hub when it returns."""

    def reset_input_buffer(self) -> None:
        self._live().reset_input()

    def reset_output_buffer(self) -> None:
        """Nothing waits here: each write went out."""

    def _update_rts_state(self) -> None:
        """RTS/DTR do not cross the hub."""

    def _update_dtr_state(self) -> None:
        """RTS/DTR do not cross the hub."""

    def _update_break_state(self) -> None:
        raise SerialException("a break does not cross the hub")

    #: no modem line crosses the hub: the port reads as a cable with the lines a program
    #: waits for (CTS, DSR, CD) asserted, and no ring
    cts = dsr = cd = property(lambda self: True)
    ri = property(lambda self: False)
