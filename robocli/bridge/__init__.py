"""Robots on Eclipse Zenoh: a bridge puts a robot's state on Zenoh for any number of
watchers and takes commands from one controller at a time (:mod:`.control`), stopping the
robot when its controller goes. :class:`PioneerBridge` (:mod:`.pioneer`), :class:`ArmBridge`
(:mod:`.arm`); the client side of a Pioneer, :class:`RemotePioneer`, is a device client
(:mod:`robocli.devices.pioneer.over_zenoh`). The key layout is in
:mod:`robocli.zenoh.robot_keys`. Needs ``robocli-robots[zenoh]``."""

from robocli.devices.pioneer.over_zenoh import RemotePioneer

__all__ = ["RemotePioneer"]
