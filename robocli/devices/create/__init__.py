"""An iRobot Create 2's sensors over its Open Interface: :class:`Create`."""

from robocli.devices.create.client import STREAMED, Create, CreateOdometry, CreateState

__all__ = ["STREAMED", "Create", "CreateOdometry", "CreateState"]
