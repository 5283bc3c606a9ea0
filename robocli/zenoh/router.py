"""A Zenoh router in router mode (``robocli router``): the lab server's, to which robots'
hubs and bridges and students' laptops connect by endpoint.

Access control: ``users``, a file of ``user:password`` lines (Zenoh's *usrpwd*
authentication): a client whose configuration does not present one of them is refused at
connection. ``acl``: besides, each user writes only under its own name
(:mod:`robocli.zenoh.acl`). Everything listens on loopback unless an endpoint or a
configuration file says otherwise.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from robocli.errors import InvalidArgument
from robocli.zenoh.acl import lab_access_control
from robocli.zenoh.session import ZenohTarget, close_session, open_session, zenoh_config

if TYPE_CHECKING:
    import zenoh

__all__ = ["Router", "check_users", "router_config", "start_router"]

MAX_USERS_BYTES = 1 << 20


@dataclass
class Router:
    """A running router: its session, its Zenoh id and where it listens."""

    session: zenoh.Session
    listen: list[str] = field(default_factory=list)

    @property
    def zid(self) -> str:
        return str(self.session.info.zid())

    def close(self) -> None:
        """Stop routing (every client's connection closes)."""
        close_session(self.session)

    def __enter__(self) -> Router:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def check_users(path: Path) -> list[str]:
    """The users of the ``user:password`` lines of ``path``; :class:`InvalidArgument` for a
    file that cannot be read or holds none, or a line that is not one."""
    try:
        with path.open("rb") as f:
            text = f.read(MAX_USERS_BYTES + 1).decode("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InvalidArgument(f"--users {path}: {exc}") from None
    lines = [line for line in text.splitlines() if line.strip()]
    bad = [i + 1 for i, line in enumerate(lines) if ":" not in line or line.startswith(":")]
    if bad or not lines:
        where = f"line {bad[0]} is not user:password" if bad else "no user:password line"
        raise InvalidArgument(f"--users {path}: {where}")
    return [line.split(":", 1)[0] for line in lines]


def router_config(users: Path | None, acl: bool = False) -> dict[str, Any]:
    """The configuration keys ``--users`` (and ``--acl``) add to a router's."""
    if users is None:
        if acl:
            raise InvalidArgument("--acl needs --users: the ACL is per authenticated user")
        return {}
    names = check_users(users)
    extra: dict[str, Any] = {"transport/auth/usrpwd": {"dictionary_file": str(users)}}
    if acl:
        try:
            extra["access_control"] = lab_access_control(names)
        except InvalidArgument as exc:
            raise InvalidArgument(f"--users {users}: {exc}") from None
    return extra


def start_router(
    target: ZenohTarget | str | None = None,
    *,
    config: Path | None = None,
    listen: str | None = None,
    users: Path | None = None,
    acl: bool = False,
) -> Router:
    """Open a Zenoh session in router mode: from ``config`` (a JSON5 file; ``listen`` added
    to its endpoints) or listening on ``target`` (default :data:`DEFAULT_ENDPOINT`).
    ``users``: accept only clients presenting a ``user:password`` of that file; ``acl``:
    and let each write only under its own name (:func:`router_config`)."""
    extra = router_config(users, acl)
    if config is not None:
        spec: ZenohTarget | str | None = ZenohTarget(config_file=config)
        if listen is not None:
            extra["listen/endpoints"] = [listen]
    else:
        spec = target
    endpoints = json.loads(zenoh_config(spec, "router", extra=extra).get_json("listen/endpoints"))
    session = open_session(spec, "router", extra=extra)
    return Router(session, [str(e) for e in endpoints])
