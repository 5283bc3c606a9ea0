"""robocli on Eclipse Zenoh: the plumbing every ``--zenoh`` command shares.

:mod:`robocli.zenoh.session` opens a session from ``--zenoh [ENDPOINT|CONFIG]`` (servers
listen, clients connect, multicast scouting off); :mod:`robocli.zenoh.keys` is the key
layout (``robocli/<name>/<topic>``, ``@info``, ``@settings``, ``@alive``), and
:mod:`robocli.zenoh.robot_keys` a robot's (state, ``@control``) with their JSON, which a
bridge serves and a remote client (:mod:`robocli.devices.pioneer.over_zenoh`) uses. The
``eclipse-zenoh`` package is optional: ``pip install 'robocli-robots[zenoh]'``; nothing here
imports it until a session is opened.
"""

from __future__ import annotations

from robocli.zenoh.keys import (
    ALIVE_ALL,
    alive_key,
    check_name,
    default_name,
    info_key,
    parse_alive,
    settings_key,
    topic_key,
)
from robocli.zenoh.session import (
    DEFAULT_ENDPOINT,
    INSTALL_HINT,
    ZenohMissing,
    ZenohTarget,
    import_zenoh,
    open_session,
    parse_target,
    zenoh_config,
)

__all__ = [
    "ALIVE_ALL",
    "DEFAULT_ENDPOINT",
    "INSTALL_HINT",
    "ZenohMissing",
    "ZenohTarget",
    "alive_key",
    "check_name",
    "default_name",
    "import_zenoh",
    "info_key",
    "open_session",
    "parse_alive",
    "parse_target",
    "settings_key",
    "topic_key",
    "zenoh_config",
]
