"""Industrial arms over ROS-Industrial Simple Message: :class:`Arm` (the client), its state."""

from robocli.devices.arm.client import Arm, SampleListener, StillMoving
from robocli.devices.arm.state import (
    ABB_MAX_POINTS,
    ArmStatus,
    JointSample,
    Point,
    Recorder,
    TooFewSamples,
)

__all__ = ["ABB_MAX_POINTS", "Arm", "ArmStatus", "JointSample", "Point", "Recorder",
           "SampleListener", "StillMoving", "TooFewSamples"]
