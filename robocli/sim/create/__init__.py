"""Built-in iRobot Create 2 simulator (Open Interface): :class:`CreateSim`."""

from robocli.sim.create.server import STREAM_PERIOD_S, CreateSim, CreateSimState

__all__ = ["STREAM_PERIOD_S", "CreateSim", "CreateSimState"]
