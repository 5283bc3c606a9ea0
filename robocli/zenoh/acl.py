"""The lab's access control: who may write which robocli key, enforced by the Zenoh router
(``robocli router --users FILE --acl``) on the user each client authenticated as.

One rule for a whole lab, so that nobody edits an ACL by hand: **a user writes only under
its own name**. Every user of the ``user:password`` file may

* *serve* as itself: put ``robocli/<user>/<topic>`` (a hub's sensors, a bridge's state),
  answer ``robocli/<user>/@info``, ``@settings/*``, ``@control`` and every
  ``@control/<holder>/*`` of its robot, declare ``robocli/<user>/@alive/*``, put
  ``robocli/<user>/@control/event``, and keep the history of its advanced publishers
  (``robocli/<user>/<topic>/@adv/**``): a hub or bridge is started with ``--name <user>``
  and the credentials of that user;
* *command* any robot as itself: put and query ``robocli/<robot>/@control/<user>/*`` and
  declare its liveliness token there. A bridge takes the controller's identity from that
  key chunk (:mod:`robocli.zenoh.robot_keys`), which the router let through only from ``<user>``;
* *read* everything: subscribe, query ``@info``, ``@control``, ``@settings`` (a hub's token
  still guards its settings), ask for liveliness tokens and advanced publishers' history.

ROS 2 on the same router (``--ros2``, rmw_zenoh's keys: :mod:`robocli.ros2.rmw`): a server
``<user>`` serves its ROS 2 topics in the namespace ``/<user>`` (``--ros2-namespace
/<user>``): it puts ``<domain>/<user>/**``, keeps their caches (``.../@adv/**``) and declares
its graph tokens (``@ros2_lv/.../%<user>/...``). Any user may put the command topics of any
robot, ``<domain>/<robot>/cmd_vel`` and ``.../joint_trajectory`` (a bridge drives them as its
one controller ``ros2``, under its usual rules: :mod:`robocli.bridge.ros2`), and declare the
graph tokens of its own ROS 2 nodes in the root namespace (what ``ros2 topic echo`` or RViz
declare). Nobody else puts on a robot's ROS 2 topics. The user name ``ros2`` is reserved.

Anything else a client sends (a put on another user's keys, a token in another user's
chunk, a queryable on another user's ``@info``) is dropped by the router. Zenoh matches
``*`` and ``**`` never to a chunk starting with ``@`` (verbatim chunks), hence the explicit
``@`` keys below. Clients must be Zenoh *clients* of the router: a *peer* may connect to
other peers directly, around the router and its ACL.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from robocli.errors import InvalidArgument
from robocli.zenoh.keys import ROOT, check_name

__all__ = ["EVERY_KEY", "RESERVED", "lab_access_control"]

EVERY_KEY = (
    "**",
    f"{ROOT}/*/@info",
    f"{ROOT}/*/@settings/*",
    f"{ROOT}/*/@alive/*",
    f"{ROOT}/*/@control",
    f"{ROOT}/*/@control/**",
    f"{ROOT}/*/*/@adv/**",
    "@ros2_lv/**",
    "*/**/@adv/**",
)
"""Every key robocli uses (``**`` alone misses the verbatim ``@`` chunks), ROS 2's graph
tokens and its transient-local publishers' caches included."""
_READ = ("declare_subscriber", "declare_liveliness_subscriber", "liveliness_query")
_ASK_KEYS = ("**", f"{ROOT}/*/@info", f"{ROOT}/*/@settings/*", f"{ROOT}/*/@control",
             f"{ROOT}/*/*/@adv/**", "*/**/@adv/**")  # fmt: skip
"""What anyone may query: not a robot's ``@control/<holder>/*`` (a holder's own)."""
_EGRESS = ("put", "delete", "query", "reply", "declare_subscriber", "declare_queryable",
           "liveliness_token", "declare_liveliness_subscriber", "liveliness_query")  # fmt: skip
_SERVE = ("put", "delete", "declare_queryable", "reply", "liveliness_token")
_COMMAND = ("put", "query", "liveliness_token")


_ROS_COMMANDS = ("*/*/cmd_vel/**", "*/*/joint_trajectory/**")
"""ROS 2 command topics of a robot in namespace ``/<robot>`` (any domain): any lab user."""
_ROS_GRAPH = "@ros2_lv/*/*/*/*/*/*"  # domain, zid, node id, entity id, kind, enclave
RESERVED = ("ros2",)
"""Names no user may take: ``ros2`` is the controller every ROS 2 publisher drives as."""


def _serve_keys(user: str) -> list[str]:
    own = f"{ROOT}/{user}"
    return [f"{own}/*", f"{own}/@info", f"{own}/@settings/*", f"{own}/@alive/*",
            f"{own}/@control", f"{own}/@control/**", f"{own}/*/@adv/**",
            f"*/{user}/**", f"*/{user}/**/@adv/**", f"{_ROS_GRAPH}/%{user}/**"]  # fmt: skip


def lab_access_control(users: Iterable[str]) -> dict[str, Any]:
    """The ``access_control`` section of a router's configuration for ``users`` (see the
    module): deny by default, everyone reads, each user writes under its own name.
    :class:`InvalidArgument` for a user name that is not one key chunk."""
    names = []
    for user in users:
        name = check_name(user, "user")
        if name in RESERVED:
            raise InvalidArgument(f"user {name!r} is reserved (ROS 2's controller name)")
        if name in names:
            raise InvalidArgument(f"user {name!r} appears twice")
        names.append(name)
    if not names:
        raise InvalidArgument("an access control needs at least one user")
    rules: list[dict[str, Any]] = [
        {"id": "read", "permission": "allow", "flows": ["ingress"], "messages": list(_READ),
         "key_exprs": list(EVERY_KEY)},
        {"id": "ask", "permission": "allow", "flows": ["ingress"], "messages": ["query"],
         "key_exprs": list(_ASK_KEYS)},
        {"id": "deliver", "permission": "allow", "flows": ["egress"],
         "messages": list(_EGRESS), "key_exprs": list(EVERY_KEY)},
        {"id": "ros2 command", "permission": "allow", "flows": ["ingress"],
         "messages": ["put", "liveliness_token"],
         "key_exprs": [*_ROS_COMMANDS, f"{_ROS_GRAPH}/%/**"]},
    ]  # fmt: skip
    subjects: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = [{"rules": ["read", "ask", "deliver", "ros2 command"],
                                       "subjects": [f"user {n}" for n in names]}]  # fmt: skip
    for name in names:
        rules.append({"id": f"serve as {name}", "permission": "allow", "flows": ["ingress"],
                      "messages": list(_SERVE), "key_exprs": _serve_keys(name)})  # fmt: skip
        rules.append({"id": f"command as {name}", "permission": "allow", "flows": ["ingress"],
                      "messages": list(_COMMAND),
                      "key_exprs": [f"{ROOT}/*/@control/{name}/*"]})  # fmt: skip
        subjects.append({"id": f"user {name}", "usernames": [name]})
        policies.append({"rules": [f"serve as {name}", f"command as {name}"],
                         "subjects": [f"user {name}"]})  # fmt: skip
    return {"enabled": True, "default_permission": "deny", "rules": rules,
            "subjects": subjects, "policies": policies}  # fmt: skip
