"""What each device gives a :class:`~robocli.io.record.Recorder`, and the channels it becomes.

Each device is recorded through its public listener hooks, as python-can's writers are:

- every frame each way on each link goes, whole and unchanged, into a raw channel
  ``/NAME/raw/[PORT/]tx|rx`` (schema :data:`~robocli.io.record.links.RAW_SCHEMA`: JSON
  with the frame's bytes in base64; metadata ``protocol``, ``direction``, ``link``,
  ``port``), which ``robocli dump ... --file`` decodes again to the same packets as the
  live dump (and those of older recordings, encoded ``robocli.raw``, too);
- the same frames are decoded in the writer thread (never in the device's) into channels
  with Foxglove's schemas or robocli's (:mod:`robocli.io.schemas`).

Topics, for a source named ``NAME`` (frames are ``NAME/odom``, ``NAME/base_link``...):

========== =================================================================================
Pioneer    ``pose`` (PoseInFrame in ``odom``), ``tf`` (FrameTransform odom -> base_link),
           ``sonar`` (LaserScan in ``base_link``, 360 one-degree bins, 0 where no sonar
           looks), ``laser`` (a simulator's laser, LaserScan), ``state`` (robocli.pioneer.State)
Arm        ``joint_states`` (JOINT_POSITION) and ``joint_feedback`` (JOINT_FEEDBACK, with the
           controller's time), both robocli.JointState; ``tcp`` (PoseInFrame of the flange
           in ``base``) and ``tf`` (FrameTransforms of every link), from the feedback when
           the controller sends it, else from JOINT_POSITION; ``status`` (robocli.arm.Status)
Hub        ``imu`` (robocli.Imu), ``adc``, ``battery``, ``sysinfo``, ``gps`` (LocationFix),
           ``laser`` (LaserScan), ``camera`` (CompressedImage for JPEG, else RawImage rgb8),
           ``stereo/left|right``, ``depth/rgb`` and ``depth/image`` (RawImage mono16, mm)
Models     ``robot_description`` (a Pioneer's and an arm's URDF, std_msgs/String, written
           once, latched; the first robot's also on ``/robot_description``, see
           :mod:`.models`); an arm's ``link_i`` frames are those of its URDF
Laser      ``scan`` (a Hokuyo's streamed scans, LaserScan in ``NAME/laser``; publish time:
           the sensor's timestamp on the host clock), ``tf`` (on a robot: FrameTransform
           from its ``base_link`` at the mount); raw channels of protocol ``scip2``
========== =================================================================================
"""

from __future__ import annotations

from typing import Any

from robocli.errors import InvalidArgument
from robocli.io.record.links import RawLink, Sink, raw_link

__all__ = ["RawLink", "attach", "raw_link"]


def attach(rec: Sink, device: Any, name: str | None = None, **options: Any) -> str:
    """Record ``device`` into ``rec`` (see :meth:`Recorder.add`); returns its name."""
    from robocli.devices.arm import Arm
    from robocli.devices.hub.client import Hub
    from robocli.devices.laser import Laser
    from robocli.devices.pioneer import Pioneer
    from robocli.io.record.arm import attach_arm
    from robocli.io.record.hub import attach_hub
    from robocli.io.record.laser import attach_laser
    from robocli.io.record.pioneer import attach_pioneer

    if isinstance(device, Pioneer):
        return attach_pioneer(rec, device, name, **options)
    if isinstance(device, Arm):
        return attach_arm(rec, device, name or "arm", **options)
    if isinstance(device, Hub):
        return attach_hub(rec, device, name or "hub", **options)
    if isinstance(device, Laser):
        return attach_laser(rec, device, name, **options)
    raise InvalidArgument(f"cannot record a {type(device).__name__}: give a Pioneer, an Arm, "
                          "a Hub or a Laser")  # fmt: skip
