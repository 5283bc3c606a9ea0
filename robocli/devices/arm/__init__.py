"""Industrial arms over ROS-Industrial Simple Message: :class:`Arm` (the client: :mod:`.client`,
the state port's tracking :mod:`.tracking`, the motion port's :mod:`.motion`, the links'
bytes :mod:`.link`), its state (:mod:`.state`) and jogging (:mod:`.teleop`)."""

from robocli.devices.arm.client import Arm, SampleListener, StillMoving
from robocli.devices.arm.state import (
    ABB_MAX_POINTS,
    ArmStatus,
    JointRecorder,
    JointSample,
    Point,
    TooFewSamples,
)

__all__ = [
    "ABB_MAX_POINTS",
    "Arm",
    "ArmStatus",
    "JointRecorder",
    "JointSample",
    "Point",
    "SampleListener",
    "StillMoving",
    "TooFewSamples",
]
