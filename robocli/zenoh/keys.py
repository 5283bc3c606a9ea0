"""The key-expression layout of robocli on Zenoh (the one place it is defined).

Everything robocli puts on Zenoh lives under ``robocli/<name>/``, ``<name>`` being a hub's
name (``serve --name``, default the host name) or a robot's (``bridge ... --name``)::

    robocli/<name>/<topic>          data: a hub's sensor (adc, imu, camera...) or a robot's
                                    state (pose, sonar, joints...); put by the server
    robocli/<name>/@info            queryable: what <name> serves, as JSON
    robocli/<name>/@settings/<topic>  queryable: change <topic>'s settings (JSON parameters
                                    in the query's payload; the token first when one is set)
    robocli/<name>/@alive/<kind>    liveliness token while <name> is up; <kind> is
                                    hub, pioneer or arm
    robocli/<name>/@control/...     a robot's command side (the bridge: commands and the
                                    liveliness of the controller holding it)
    robocli/<name>/serial-<port>    the bytes a hub's serial port sent, put by the hub for
                                    the user streaming it; that user's side is
                                    robocli/<name>/@control/<user>/serial-open (query),
                                    serial-write (put), serial-alive (liveliness),
                                    serial-error (put by the hub)

Chunks starting with ``@`` are *verbatim* in Zenoh: the wildcards ``*`` and ``**`` never
match them, so ``robocli/hub1/**`` subscribes to data only, never to the queryables and
tokens beside it. ``robocli list`` queries the liveliness tokens ``robocli/*/@alive/*``.

A name is one key chunk: letters, digits, ``-``, ``_``, ``.`` (a host name), not starting
with ``@``.
"""

from __future__ import annotations

import re
import socket

from robocli.errors import InvalidArgument

__all__ = [
    "ALIVE_ALL",
    "KINDS",
    "ROOT",
    "alive_key",
    "check_name",
    "default_name",
    "info_key",
    "SERIAL_PARTS",
    "parse_alive",
    "serial_data_key",
    "serial_holder",
    "serial_key",
    "settings_key",
    "topic_key",
]

ROOT = "robocli"
KINDS = ("hub", "pioneer", "arm")
"""What a liveliness token says is up under a name."""
ALIVE_ALL = f"{ROOT}/*/@alive/*"
"""Every robocli server's liveliness token (what ``robocli list`` asks for)."""
_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]{0,62}")


def check_name(name: str, what: str = "name") -> str:
    """``name`` if it can be one key chunk (:data:`_NAME`), else :class:`InvalidArgument`."""
    if not isinstance(name, str) or not _NAME.fullmatch(name):
        raise InvalidArgument(
            f"{what} {name!r}: use letters, digits, '-', '_', '.' (up to 63, not starting "
            "with '@' or '.')"
        )
    return name


def default_name() -> str:
    """This machine's host name as a key chunk (its first label; ``robocli`` if unusable)."""
    host = socket.gethostname().split(".")[0]
    host = re.sub(r"[^A-Za-z0-9_\-]", "-", host)[:63]
    return host if _NAME.fullmatch(host) else ROOT


def topic_key(name: str, topic: str) -> str:
    """``robocli/<name>/<topic>``: where ``name`` puts ``topic`` (a sensor, a state)."""
    return f"{ROOT}/{check_name(name)}/{check_name(topic, 'topic')}"


def info_key(name: str) -> str:
    """``robocli/<name>/@info``: the queryable telling what ``name`` serves."""
    return f"{ROOT}/{check_name(name)}/@info"


def settings_key(name: str, topic: str | None = None) -> str:
    """``robocli/<name>/@settings/<topic>`` (``topic`` None: ``*``, every topic)."""
    tail = "*" if topic is None else check_name(topic, "topic")
    return f"{ROOT}/{check_name(name)}/@settings/{tail}"


def alive_key(name: str, kind: str) -> str:
    """``robocli/<name>/@alive/<kind>``: the liveliness token of a server that is up."""
    if kind not in KINDS:
        raise InvalidArgument(f"kind {kind!r}: one of {', '.join(KINDS)}")
    return f"{ROOT}/{check_name(name)}/@alive/{kind}"


def parse_alive(key: str) -> tuple[str, str] | None:
    """``(name, kind)`` of a liveliness key of this layout, None for any other key."""
    parts = str(key).split("/")
    if len(parts) == 4 and parts[0] == ROOT and parts[2] == "@alive" and parts[3] in KINDS:
        return parts[1], parts[3]
    return None


SERIAL_PARTS = ("serial-open", "serial-write", "serial-alive", "serial-error")
"""What lies under ``robocli/<hub>/@control/<user>/`` for a hub's serial stream."""


def serial_key(name: str, user: str | None, part: str) -> str:
    """``robocli/<name>/@control/<user>/<part>`` (``user`` None: ``*``, any user)."""
    if part not in SERIAL_PARTS:
        raise InvalidArgument(f"part {part!r}: one of {', '.join(SERIAL_PARTS)}")
    who = "*" if user is None else check_name(user, "user")
    return f"{ROOT}/{check_name(name)}/@control/{who}/{part}"


def serial_holder(key: object, name: str, part: str) -> str | None:
    """The user a :func:`serial_key` names (the key chunk the router checked under the lab's
    ACL), None for any other key."""
    parts = str(key).split("/")
    if len(parts) != 5 or parts[:3] != [ROOT, name, "@control"] or parts[4] != part:
        return None
    return parts[3] if _NAME.fullmatch(parts[3]) else None


def serial_data_key(name: str, port: str) -> str:
    """``robocli/<name>/serial-<port>``: the port's name as one chunk (``/dev/ttyUSB0`` ->
    ``serial-dev_ttyUSB0``)."""
    chunk = re.sub(r"[^A-Za-z0-9_.\-]", "_", port.strip("/"))[:55] or "port"
    return f"{ROOT}/{check_name(name)}/serial-{chunk}"
