"""The one exception tree of robocli.

Every error the library raises derives from :class:`RobocliError`. The CLI maps each class
to a one-line message and an exit code (:attr:`RobocliError.exit_code`).
"""

from __future__ import annotations

import builtins

EXIT_OK = 0
EXIT_FAILURE = 1
EXIT_USAGE = 2
EXIT_UNREACHABLE = 3
EXIT_REFUSED = 4
EXIT_INTERRUPTED = 130


class RobocliError(Exception):
    """Base of every robocli error."""

    exit_code: int = EXIT_FAILURE


class TransportError(RobocliError):
    """A byte stream could not be opened, or failed / closed while in use."""

    exit_code = EXIT_UNREACHABLE


class ConnectionLost(TransportError):
    """The peer closed the stream or the link dropped while a session was open."""

    exit_code = EXIT_FAILURE


class StaleWrite(TransportError):
    """A write that had not begun by its latest start time (the writing program stalled):
    nothing of it was sent. The session asks the device what to send instead (a stop)."""

    exit_code = EXIT_FAILURE


class FramingError(RobocliError):
    """Bytes that do not form a frame of the protocol."""


class ChecksumError(FramingError):
    """A frame whose checksum does not match its contents."""


class ProtocolError(RobocliError):
    """A well-framed message that is not what the protocol allows at this point."""


class DeviceError(RobocliError):
    """The device answered but refused or failed the request.

    ``code`` carries the device's own code (reply code, error number, ...) when it has one.
    """

    exit_code = EXIT_REFUSED

    def __init__(self, message: str, code: int | None = None) -> None:
        super().__init__(message)
        self.code = code


class UnknownRobotError(DeviceError):
    """The robot identified itself with a subtype robocli has no parameters for."""


class InvalidArgument(RobocliError, ValueError):
    """A value the caller gave is not one the robot or the protocol can take (NaN, a string
    for a number, out of range); the message names the argument. Also a ``ValueError``."""

    exit_code = EXIT_USAGE


class TimeoutError(RobocliError, builtins.TimeoutError):
    """A device did not answer in time. Also a :class:`builtins.TimeoutError`."""

    exit_code = EXIT_UNREACHABLE


__all__ = [
    "ChecksumError",
    "ConnectionLost",
    "DeviceError",
    "FramingError",
    "InvalidArgument",
    "ProtocolError",
    "RobocliError",
    "StaleWrite",
    "TimeoutError",
    "TransportError",
    "UnknownRobotError",
]
