"""Running a device, a server or a long step from a script as the CLI does: ``kill``
(SIGTERM) stopping it as Ctrl-C does, a bounded step that a second Ctrl-C must not cut,
the errors of binding a server's address, and a robot that resets the link while
connecting explained as busy."""

from __future__ import annotations

import contextlib
import errno
import signal
import socket
from collections.abc import Iterator

from robocli.errors import InvalidArgument, RobocliError, TransportError

__all__ = ["listening", "shielded", "sigterm_as_interrupt"]


@contextlib.contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """Let `kill` (SIGTERM) stop the block the way Ctrl-C does (a :class:`KeyboardInterrupt`
    inside it): robots stop, ports close. Outside the main thread, nothing changes."""

    def _raise(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    try:
        previous = signal.signal(signal.SIGTERM, _raise)
    except ValueError:  # not the main thread (e.g. called from a test runner thread)
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextlib.contextmanager
def shielded() -> Iterator[None]:
    """Ctrl-C and SIGTERM are ignored inside (a bounded step, such as writing a recording
    on the way out): a second Ctrl-C must not leave the file half written."""
    try:
        saved = [(s, signal.signal(s, signal.SIG_IGN)) for s in (signal.SIGINT, signal.SIGTERM)]
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        for sig, handler in saved:
            signal.signal(sig, handler)


@contextlib.contextmanager
def listening(address: str) -> Iterator[None]:
    """Around a server's bind on ``address``: a port already in use is no robot out of reach
    (:class:`TransportError`, exit 3) but a :class:`RobocliError` (exit 1); an address that
    is not this machine's, or no address at all, an :class:`InvalidArgument` (exit 2)."""
    try:
        yield
    except InvalidArgument:
        raise
    except UnicodeError as exc:  # the IDNA codec of the resolver: an empty label ("a..b")
        why = str(exc.__cause__ or exc.__context__ or exc).removeprefix("UnicodeError: ")
        raise InvalidArgument(f"cannot listen on {address!r}: not a host name ({why})") from None
    except TransportError as exc:
        cause = exc.__cause__
        if isinstance(cause, (socket.gaierror, UnicodeError)) or (
            isinstance(cause, OSError) and cause.errno == errno.EADDRNOTAVAIL
        ):
            raise InvalidArgument(
                f"{exc} (give an address of this machine, e.g. 127.0.0.1)"
            ) from None
        raise RobocliError(str(exc)) from None
