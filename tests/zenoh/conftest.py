"""Zenoh tests: loopback only, multicast scouting off, explicit endpoints on ephemeral ports
(the ``endpoint`` fixture of tests/conftest.py).
Skipped as a whole when the optional ``eclipse-zenoh`` package is not installed (it is in
the ``test`` extra); the test of the message without it blocks the import itself."""

from __future__ import annotations

import pytest

pytest.importorskip("zenoh", reason="needs robocli-robots[zenoh] (eclipse-zenoh)")
