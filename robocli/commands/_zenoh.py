"""The ``--zenoh [ENDPOINT|CONFIG]`` option every Zenoh-capable command declares alike.

One meaning (:mod:`robocli.zenoh.session`): a server (``serve``, ``bridge``, ``router``)
listens on ENDPOINT, a client (``subscribe``, ``connect``, ``teleop``, ``list``) connects
to it; a JSON5 file is taken as the whole configuration. ``--zenoh`` alone is the default
endpoint, tcp/127.0.0.1:7447 (Typer has no option with an optional value: the command's
class, :class:`ZenohCommand`, gives ``--zenoh`` followed by nothing or by another option the
default). Declare it with :func:`zenoh_option`, register the command with
``cls=ZenohCommand``, and open the session with :func:`zenoh_session`, which turns a bad
value into a usage error (exit 2).
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING, Any

import typer

from robocli.commands._common import PlainCommand
from robocli.zenoh.session import DEFAULT_ENDPOINT, Role, ZenohTarget, parse_target

if TYPE_CHECKING:
    import zenoh


__all__ = [
    "ZENOH_METAVAR",
    "ZenohCommand",
    "with_default_zenoh",
    "zenoh_option",
    "server_name",
    "zenoh_session",
    "zenoh_target",
]

ZENOH_METAVAR = "[ENDPOINT|CONFIG]"
_VERB = {"server": "listen on", "router": "listen on", "client": "connect to"}


def with_default_zenoh(args: list[str]) -> list[str]:
    """``args`` with a ``--zenoh`` that has no value (last, or followed by an option) given
    :data:`DEFAULT_ENDPOINT`. Arguments after ``--`` are left alone."""
    out = list(args)
    end = out.index("--") if "--" in out else len(out)
    for i in range(end):
        if out[i] == "--zenoh" and (i + 1 >= end or out[i + 1].startswith("-")):
            out[i] = f"--zenoh={DEFAULT_ENDPOINT}"
    return out


class ZenohCommand(PlainCommand):
    """A :class:`PlainCommand` whose ``--zenoh`` value may be left out."""

    def parse_args(self, ctx: Any, args: list[str]) -> list[str]:
        return super().parse_args(ctx, with_default_zenoh(args))


def zenoh_option(role: Role, *, default: str | None = None) -> Any:
    """The ``--zenoh`` Typer option for a command of ``role`` (registered with
    ``cls=ZenohCommand``, its value may be left out: :data:`DEFAULT_ENDPOINT`).
    ``default``: the value when ``--zenoh`` is not given at all (None: the command does not
    use Zenoh then)."""
    return typer.Option(default, "--zenoh", metavar=ZENOH_METAVAR, show_default=False,
                        help=f"Use Eclipse Zenoh: {_VERB[role]} ENDPOINT (alone: "
                        f"{DEFAULT_ENDPOINT}; multicast scouting off), or take CONFIG, a Zenoh "
                        "JSON5 file. Needs robocli-robots[zenoh].")  # fmt: skip


def zenoh_target(value: str | None) -> ZenohTarget:
    """``--zenoh``'s value as a target; a bad one is a usage error (exit 2)."""
    from robocli.errors import InvalidArgument

    try:
        return parse_target(value)
    except InvalidArgument as exc:
        message = re.sub(r"^--zenoh:? ", "", str(exc))
        raise typer.BadParameter(message, param_hint="'--zenoh'") from None


def server_name(name: str | None, value: str | None, fallback: str) -> str:
    """A hub's or bridge's ``--name``: given, else the user the ``--zenoh`` configuration
    authenticates as (a lab router's ACL lets a user serve under its own name only), else
    ``fallback``. A name that is not that user is said on stderr (one line): under the
    ACL, what it puts is dropped. A bad name is a usage error (exit 2)."""
    from robocli.errors import InvalidArgument
    from robocli.zenoh.keys import check_name
    from robocli.zenoh.session import config_user

    user = config_user(zenoh_target(value))
    try:
        chosen = check_name(name if name is not None else user or fallback, "--name")
    except InvalidArgument as exc:
        raise typer.BadParameter(str(exc).removeprefix("--name "), param_hint="'--name'") from None
    if user is not None and chosen != user:
        typer.echo(f"robocli: warning: --name {chosen} is not the configuration's user {user}: "
                   f"a router with --acl drops what {chosen} puts", err=True)  # fmt: skip
    return chosen


def zenoh_session(value: str | None, role: Role) -> zenoh.Session:
    """The session ``--zenoh value`` means for ``role`` (the extra missing: one line, exit 1;
    nobody reached or the port taken: exit 3)."""
    from robocli.zenoh.session import open_session

    return open_session(zenoh_target(value), role)


Ros2Opt = typer.Option(False, "--ros2", help="Also appear as a ROS 2 node on the same Zenoh "
                       "session, as rmw_zenoh_cpp lays ROS 2 topics (needs robocli-robots[ros2]; "
                       "see docs/ros2.md).")  # fmt: skip
Ros2DomainOpt = typer.Option(0, "--ros2-domain", min=0, max=232, metavar="ID",
                             envvar="ROS_DOMAIN_ID", help="The ROS domain id of --ros2 (default: "
                             "$ROS_DOMAIN_ID, else 0).")  # fmt: skip
Ros2NamespaceOpt = typer.Option("", "--ros2-namespace", metavar="NS", help="The ROS 2 namespace "
                                "of --ros2's node and topics (default: the root).")  # fmt: skip


def ros2_check(ros2: bool, zenoh: str | None) -> None:
    """``--ros2`` needs ``--zenoh`` and the ``ros2`` extra: a usage error or one line now,
    before anything connects."""
    if not ros2:
        return
    if zenoh is None:
        raise typer.BadParameter("--ros2 puts ROS 2 topics on Zenoh: give --zenoh too")
    from robocli.ros2.types import node_types

    node_types()
