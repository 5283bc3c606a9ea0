"""Opening a Zenoh session from the one meaning of ``--zenoh [ENDPOINT|CONFIG]``.

* On a **server** (``serve``, ``bridge``) the session is a peer that LISTENS on ENDPOINT;
  on a **router** (``router``) a router that listens there; on a **client** (``subscribe``,
  ``connect``, ``teleop``, ``list``) a client that CONNECTS to it.
* ENDPOINT is a Zenoh locator, ``PROTO/ADDRESS`` (``tcp/127.0.0.1:7447``,
  ``tcp/10.0.0.1:7447``, ``tls/lab-server:7447``); the default is
  :data:`DEFAULT_ENDPOINT`, on loopback. Multicast scouting is off whenever an endpoint is
  given: nothing is discovered or exposed beyond the endpoint named; and so is Zenoh's
  shared-memory transport, which would carry large messages between two processes of one
  host (network namespaces too) around the endpoint.
* CONFIG is a path to a Zenoh JSON5 configuration file (an existing file, or a name ending
  in ``.json5``/``.json``/``.yaml``): it is taken as it is (mode, endpoints, scouting,
  access control: see the README's Zenoh section), with timestamping enabled for the
  history of the hub's samples; a server's or router's file that names no listen endpoint
  listens on :data:`DEFAULT_ENDPOINT` (Zenoh's own default is every interface).

The ``eclipse-zenoh`` package is optional (``pip install 'robocli-robots[zenoh]'``); without it
every function here raises :class:`ZenohMissing`, one line saying how to install it.
"""

from __future__ import annotations

import json
import logging
import re
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any, Literal

from robocli.errors import EXIT_FAILURE, InvalidArgument, RobocliError, TransportError

if TYPE_CHECKING:
    import zenoh

__all__ = [
    "DEFAULT_ENDPOINT",
    "INSTALL_HINT",
    "Role",
    "ZenohMissing",
    "ZenohTarget",
    "close_session",
    "config_user",
    "import_zenoh",
    "open_session",
    "parse_target",
    "undeclare",
    "zenoh_config",
]

DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"
"""Where ``--zenoh`` without a value listens (servers) or connects (clients): loopback."""
INSTALL_HINT = "pip install 'robocli-robots[zenoh]'"
Role = Literal["server", "client", "router"]
_ENDPOINT = re.compile(r"[a-z][a-z0-9\-]*/\S+")
_CONFIG_SUFFIXES = (".json5", ".json", ".yaml", ".yml")


class ZenohMissing(RobocliError):
    """The optional ``eclipse-zenoh`` package is not installed (exit 1)."""

    exit_code = EXIT_FAILURE


def import_zenoh() -> ModuleType:
    """The ``zenoh`` module, or :class:`ZenohMissing` saying in one line how to install it."""
    try:
        import zenoh
    except ImportError:
        raise ZenohMissing(f"Zenoh support needs Eclipse Zenoh: {INSTALL_HINT}") from None
    return zenoh


@dataclass(frozen=True)
class ZenohTarget:
    """What ``--zenoh`` named: an endpoint, or a configuration file (one of them)."""

    endpoint: str | None = None
    config_file: Path | None = None

    def __str__(self) -> str:
        return self.endpoint if self.endpoint is not None else str(self.config_file)


def parse_target(spec: str | None) -> ZenohTarget:
    """``--zenoh``'s value: None or empty is :data:`DEFAULT_ENDPOINT`; a path to a file (or
    a name ending in .json5/.json/.yaml) is a configuration; ``PROTO/ADDRESS`` an endpoint.
    Anything else is an :class:`InvalidArgument`."""
    text = (spec or "").strip()
    if not text:
        return ZenohTarget(endpoint=DEFAULT_ENDPOINT)
    path = Path(text).expanduser()
    if path.suffix.lower() in _CONFIG_SUFFIXES or path.is_file():
        if not path.is_file():
            raise InvalidArgument(f"--zenoh: no configuration file {text}")
        return ZenohTarget(config_file=path)
    if not _ENDPOINT.fullmatch(text):
        raise InvalidArgument(
            f"--zenoh {text!r}: neither an endpoint (tcp/HOST:PORT) nor a configuration file"
        )
    return ZenohTarget(endpoint=text)


def zenoh_config(
    spec: str | ZenohTarget | None, role: Role, *, extra: dict[str, Any] | None = None
) -> zenoh.Config:
    """The Zenoh configuration ``--zenoh spec`` means for ``role`` (see the module's text).
    ``extra``: more configuration keys (``"transport/auth/usrpwd"``: a value), set last."""
    z = import_zenoh()
    target = spec if isinstance(spec, ZenohTarget) else parse_target(spec)
    if target.config_file is not None:
        try:
            config: zenoh.Config = z.Config.from_file(str(target.config_file))
        except Exception as exc:
            raise InvalidArgument(f"--zenoh {target.config_file}: {_first_line(exc)}") from None
        if role == "router":
            config.insert_json5("mode", '"router"')
        listens = role != "client" and json.loads(config.get_json("mode")) != "client"
        if listens and not isinstance(json.loads(config.get_json("listen/endpoints")), list):
            # not set in the file: Zenoh's default is every interface; ours is loopback. A
            # server whose file says client mode (a lab's ACL) listens nowhere: all it says
            # goes through the router, which checks it
            config.insert_json5("listen/endpoints", json.dumps([DEFAULT_ENDPOINT]))
    else:
        config = z.Config()
        mode = {"server": "peer", "client": "client", "router": "router"}[role]
        config.insert_json5("mode", json.dumps(mode))
        where = "connect" if role == "client" else "listen"
        config.insert_json5(f"{where}/endpoints", json.dumps([target.endpoint]))
        config.insert_json5("scouting/multicast/enabled", "false")
        # Zenoh hands messages over 3 KiB to a peer on the same host through shared memory:
        # past the endpoint, and past a network namespace's shaped link. Named: it is used.
        config.insert_json5("transport/shared_memory/enabled", "false")
    config.insert_json5("timestamping/enabled", "true")
    for key, value in (extra or {}).items():
        config.insert_json5(key, json.dumps(value))
    return config


def config_user(spec: str | ZenohTarget | None) -> str | None:
    """The user name a configuration authenticates as (``transport/auth/usrpwd/user``), or
    None (an endpoint, or a file without one)."""
    target = spec if isinstance(spec, ZenohTarget) else parse_target(spec)
    if target.config_file is None:
        return None
    user = json.loads(zenoh_config(target, "client").get_json("transport/auth/usrpwd/user"))
    return user if isinstance(user, str) and user else None


def open_session(
    spec: str | ZenohTarget | None, role: Role, *, extra: dict[str, Any] | None = None
) -> zenoh.Session:
    """A Zenoh session as ``--zenoh spec`` means for ``role``. A server that cannot listen
    or a client that reaches nobody is a :class:`TransportError` (exit 3), one line."""
    z = import_zenoh()
    target = spec if isinstance(spec, ZenohTarget) else parse_target(spec)
    config = zenoh_config(target, role, extra=extra)
    try:
        session: zenoh.Session = z.open(config)
    except Exception as exc:
        verb = "connect to" if role == "client" else "listen on"
        raise TransportError(f"zenoh: cannot {verb} {target}: {_first_line(exc)}") from None
    return session


def close_session(session: Any) -> None:
    """Close a Zenoh session (bounded by Zenoh; its declarations go with it). Idempotent."""
    session.close()


def undeclare(entity: Any) -> None:
    """Undeclare a Zenoh entity; one of a session already closed is left (logged)."""
    try:
        entity.undeclare()
    except import_zenoh().ZError:
        logging.getLogger(__name__).debug("undeclare failed", exc_info=True)


def _first_line(exc: BaseException) -> str:
    """Zenoh's message without the Rust source location it appends."""
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
    return re.sub(r"\s+at /\S+?\.rs:\d+\.?", "", text).rstrip(". ")  # at its end, or before a ]
