"""The ROS 2 sink bounds what waits for its thread, in items and in bytes: a device that
sends faster than ROS 2 takes (camera frames) has the excess dropped and counted, never
queued without end."""

from __future__ import annotations

import threading

import pytest

from robocli.ros2.live import Ros2Topics
from robocli.ros2.node import Ros2Node
from robocli.zenoh.session import close_session, open_session
from tests.waiting import wait_for

pytest.importorskip("zenoh", reason="needs robocli-robots[zenoh] (eclipse-zenoh)")


def test_the_sink_drops_what_goes_past_its_bytes_and_counts_it(endpoint) -> None:
    session = open_session(endpoint, "server")
    node = Ros2Node(session, "sink")
    topics = Ros2Topics(node, "sink", max_queue_bytes=1000)
    gate, done = threading.Event(), []
    try:
        assert topics.put(gate.wait, (20.0,), 100)  # holds the sink's thread
        wait_for(lambda: topics._queue.empty(), "the sink's thread busy")
        assert topics.put(done.append, (1,), 600)
        assert not topics.put(done.append, (2,), 600)  # 100 + 600 + 600 > 1000
        assert topics.dropped == 1
        gate.set()
        wait_for(lambda: done == [1], "the queued item handled")
        assert topics.put(done.append, (3,), 900)  # the bytes came back
        wait_for(lambda: done == [1, 3], "the next item handled")
    finally:
        gate.set()
        topics.close()
        node.close()
        close_session(session)
