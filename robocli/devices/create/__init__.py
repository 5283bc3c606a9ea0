"""An iRobot Create 2's sensors over its Open Interface: :class:`Create`."""

from robocli.devices.create.client import STREAMED, Create, CreateState, Odometry

__all__ = ["STREAMED", "Create", "CreateState", "Odometry"]
