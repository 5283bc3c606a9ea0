"""Bridge tests: each bridge runs over a loopback Zenoh router; skipped as a whole when the
optional ``eclipse-zenoh`` package is not installed (it is in the ``test`` extra)."""

from __future__ import annotations

import pytest

pytest.importorskip("zenoh", reason="needs robocli-robots[zenoh] (eclipse-zenoh)")
