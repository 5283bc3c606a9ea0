"""Zenoh tests: loopback only, multicast scouting off, explicit endpoints on ephemeral ports.
Skipped as a whole when the optional ``eclipse-zenoh`` package is not installed (it is in
the ``test`` extra); the test of the message without it blocks the import itself."""

from __future__ import annotations

import socket

import pytest

pytest.importorskip("zenoh", reason="needs robocli-robots[zenoh] (eclipse-zenoh)")


def free_endpoint() -> str:
    """``tcp/127.0.0.1:PORT`` on a port free a moment ago (Zenoh does not report the port
    it took for port 0, so the test asks the kernel for one first)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{s.getsockname()[1]}"


@pytest.fixture
def endpoint() -> str:
    return free_endpoint()
