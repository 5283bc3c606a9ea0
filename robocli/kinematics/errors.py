"""Errors of the kinematics layer: all are usage errors (exit code 2) and also ``ValueError``."""

from __future__ import annotations

from robocli.errors import EXIT_USAGE, RobocliError


class KinematicsError(RobocliError, ValueError):
    """A robot model, a target or a trajectory that robocli cannot use as given."""

    exit_code = EXIT_USAGE


class UnknownModelError(KinematicsError):
    """No robot model of that name ships with robocli (the message lists the known ones)."""


class ModelFileError(KinematicsError):
    """A robot model file that is not valid (missing key, wrong length, NaN, ...)."""


class UnreachableError(KinematicsError):
    """A Cartesian target outside the workspace or the joint limits.

    ``index`` is the point's index in its trajectory (``None`` for a single target) and
    ``position`` the target position in metres.
    """

    def __init__(
        self,
        message: str,
        index: int | None = None,
        position: tuple[float, float, float] | None = None,
    ) -> None:
        super().__init__(message)
        self.index = index
        self.position = position


class LimitError(KinematicsError):
    """A trajectory that leaves a joint's range or exceeds a joint's speed limit."""


class ValidationError(KinematicsError):
    """Two logs that cannot be compared (joint counts differ, no overlap after alignment)."""
