"""Robots on Eclipse Zenoh: a bridge puts a robot's state on Zenoh for any number of
watchers and takes commands from one controller at a time (:mod:`.control`), stopping the
robot when its controller goes. :class:`PioneerBridge` (:mod:`.pioneer`), :class:`ArmBridge`
(:mod:`.arm`), and the client side of a Pioneer, :class:`RemotePioneer` (:mod:`.remote`).
The key layout is in :mod:`.keys`. Needs ``robocli-robots[zenoh]``."""

from robocli.bridge.remote import RemotePioneer

__all__ = ["RemotePioneer"]
