"""Robot models in recordings and live views: a device's URDF (:mod:`robocli.robots.urdf`,
its link names prefixed with the device's name, as its frames are) written once when the
device is added, on ``/NAME/robot_description``, and, for the first robot of a recording or
view, on ``/robot_description`` too: the topic the 3D panel of Foxglove and Lichtblick loads
a robot from (shown once ticked in its topic list; any ``std_msgs/String`` topic can be
picked in a URDF custom layer). The channels' metadata says ``latched``: a live view sends
the model to every client that subscribes later, as a ROS latched topic does.

The robot then moves with its transforms: the Pioneer's ``odom -> base_link``, the arm's
:func:`~robocli.robots.urdf.arm_transforms` of every joint (the URDF's fixed joints are the
viewer's to add, as it does from the model).
"""

from __future__ import annotations

import time

from robocli.io.record.links import Sink, json_text

__all__ = ["DESCRIPTION_SCHEMA", "DESCRIPTION_TOPIC", "LATCHED", "add_model"]

#: The schema name the viewers accept a robot description in.
DESCRIPTION_SCHEMA = "std_msgs/String"
#: The topic a viewer loads a robot model from without being told.
DESCRIPTION_TOPIC = "/robot_description"
#: The channel metadata of a topic whose last message a late subscriber gets.
LATCHED = {"latched": "true"}


def add_model(rec: Sink, name: str, urdf: str) -> None:
    """Queue the device ``name``'s model ``urdf`` for ``rec``'s writer thread (at once: it
    comes before the device's first frames)."""
    # the first robot of a recording takes the viewers' topic; the name is reserved so
    first = rec.unique_name(DESCRIPTION_TOPIC.strip("/")) == DESCRIPTION_TOPIC.strip("/")
    topics = [f"/{name}{DESCRIPTION_TOPIC}", *([DESCRIPTION_TOPIC] if first else [])]
    rec.put(_write, (rec, topics, json_text({"data": urdf}).encode(),
                     rec.log_ns(time.monotonic())), len(urdf))  # fmt: skip


def _write(rec: Sink, topics: list[str], data: bytes, ns: int) -> None:
    for topic in topics:
        rec.write(rec.channel(topic, DESCRIPTION_SCHEMA, metadata=LATCHED), data, ns)
