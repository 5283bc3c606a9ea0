"""What the ``--ros2`` tests share: a loopback Zenoh router (multicast scouting off), a
configuration that makes a robocli server a client of it, and ``zenoh-ros2-sdk`` (an
independent Python implementation of rmw_zenoh) set up on that router with the ``.msg``
files of the standard types (written from rosbags' type store: the SDK computes each type's
RIHS01 hash from them itself). A test module that imports it is skipped without Zenoh."""

from __future__ import annotations

import contextlib
import json
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from tests.bridge.bridge_helpers import robocli_process
from tests.peers import free_endpoint

pytest.importorskip("zenoh", reason="needs robocli-robots[zenoh] (eclipse-zenoh)")

__all__ = ["client_config", "node_names", "robocli_process", "router", "sdk", "topics"]

_RULE = "=" * 80 + "\n"


@contextlib.contextmanager
def router() -> Iterator[tuple[str, int]]:
    """A Zenoh router on a free loopback port: (endpoint, port)."""
    from robocli.zenoh.session import close_session, open_session

    endpoint = free_endpoint()
    session = open_session(endpoint, "router")
    try:
        yield endpoint, int(endpoint.rsplit(":", 1)[1])
    finally:
        close_session(session)


def client_config(folder: Path, endpoint: str) -> str:
    """A Zenoh configuration file: a client of the router at ``endpoint``, scouting off."""
    path = folder / "client.json5"
    path.write_text(json.dumps({"mode": "client", "connect": {"endpoints": [endpoint]},
                                "scouting": {"multicast": {"enabled": False}}}))  # fmt: skip
    return str(path)


def write_msgs(folder: Path, types: list[str]) -> Path:
    """``<pkg>/msg/<Name>.msg`` of each type and its dependencies, from rosbags' store."""
    from robocli.ros2.types import typestore

    store = typestore()
    for msgtype in types:
        text, _ = store.generate_msgdef(msgtype, ros_version=2)
        for i, part in enumerate(text.split(_RULE)):
            name, body = msgtype, part
            if i:
                first, body = part.split("\n", 1)
                pkg, short = first.removeprefix("MSG: ").split("/")
                name = f"{pkg}/msg/{short}"
            pkg, _, short = name.split("/")
            path = folder / pkg / "msg" / f"{short}.msg"
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(body.strip() + "\n")
    return folder


@contextlib.contextmanager
def sdk(folder: Path, port: int, types: list[str]) -> Iterator[Any]:
    """The ``zenoh_ros2_sdk`` module, its one session a peer of the router on ``port``
    (its process-wide singletons reset before and after)."""
    sdk_module = pytest.importorskip("zenoh_ros2_sdk", reason="needs zenoh-ros2-sdk (test)")
    from zenoh_ros2_sdk import message_registry
    from zenoh_ros2_sdk.session import ZenohSession

    def reset() -> None:
        if ZenohSession._instance is not None:
            ZenohSession._instance.session.close()
        ZenohSession._instance = None
        message_registry._registry = None

    reset()
    sdk_module.get_registry(str(write_msgs(folder, types)))
    ZenohSession.get_instance("127.0.0.1", port)
    try:
        yield sdk_module
    finally:
        reset()


def topics(sdk_module: Any, port: int, want: set[str], timeout: float = 20.0) -> dict[str, Any]:
    """``ros2 topic list -t`` through the SDK, polled until it holds every topic of
    ``want`` (or ``timeout`` s: then what it has)."""
    deadline = time.monotonic() + timeout
    while True:
        found = dict(sdk_module.get_topic_names_and_types(router_port=port, timeout=1.0))
        if want <= set(found) or time.monotonic() > deadline:
            return found


def node_names(session: Any, domain: int = 0) -> set[str]:
    """The names of the nodes whose ``NN`` tokens are up (``ros2 node list``)."""
    from robocli.ros2.rmw import parse_token

    names = set()
    for reply in session.liveliness().get(f"@ros2_lv/{domain}/**", timeout=2.0):
        if reply.ok is not None:
            token = parse_token(str(reply.ok.key_expr))
            if token.kind == "NN":
                names.add(token.namespace.rstrip("/") + "/" + token.node)
    return names
