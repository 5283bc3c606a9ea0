"""The keys of a robot on Zenoh (beside those of :mod:`robocli.zenoh.keys`), and the JSON
their payloads are written in.

A bridge named ``<robot>`` uses, under ``robocli/<robot>/``:

==========================================  ===================================================
``robocli/<robot>/state``                   put per state message (a Pioneer's SIP, an arm's
                                            joint sample)
``robocli/<robot>/laser``                   put per laser scan (a Pioneer with a laser)
``robocli/<robot>/status``                  put per STATUS message (an arm)
``robocli/<robot>/@info``                   queryable: what the robot is, its keys, its holder
``robocli/<robot>/@alive/<kind>``           liveliness token while the bridge is up (``pioneer``
                                            or ``arm``): what ``robocli list --zenoh`` shows
``robocli/<robot>/@control``                queryable: who holds the robot
``robocli/<robot>/@control/event``          put per control event (granted, refused, stopped,
                                            released, fault)
``robocli/<robot>/@control/<holder>/*``     the keys of controller ``<holder>``: ``request``
                                            (queryable: acquire, release), ``alive`` (its
                                            liveliness token while it holds the robot),
                                            ``velocity`` (put: a Pioneer's set-point),
                                            ``trajectory`` (queryable: an arm's upload)
==========================================  ===================================================

Every payload is UTF-8 JSON with the Zenoh encoding ``application/json``, in SI units, ``t``
in Unix epoch seconds: any Zenoh program can watch and drive a robot without robocli.

A controller is who the KEY says, never a name in a payload: ``<holder>`` is the key chunk
after ``@control``, and under a lab router's ACL (``robocli router --users FILE --acl``,
:mod:`robocli.zenoh.acl`) only the user of that name may put, query or declare a token
there. Without the ACL the chunk is a name a controller chose, a claim.
"""

from __future__ import annotations

import json
import logging
import math
from typing import Any

from robocli.errors import InvalidArgument, ProtocolError
from robocli.zenoh.keys import ROOT, check_name
from robocli.zenoh.payload import decode_object
from robocli.zenoh.session import undeclare

JSON_ENCODING = "application/json"
#: The largest command or control payload a bridge decodes (bytes): a trajectory of a few
#: thousand points fits
MAX_PAYLOAD = 4 << 20


def control_key(robot: str, part: str | None = None) -> str:
    """``robocli/<robot>/@control`` (with ``part``: ``.../@control/<part>``)."""
    base = f"{ROOT}/{check_name(robot)}/@control"
    return base if part is None else f"{base}/{part}"


HOLDER_PARTS = ("request", "alive", "velocity", "trajectory")
"""What lies under ``robocli/<robot>/@control/<holder>/``."""


def holder_key(robot: str, holder: str | None, part: str) -> str:
    """``robocli/<robot>/@control/<holder>/<part>`` (``holder`` None: ``*``, any holder)."""
    if part not in HOLDER_PARTS:
        raise InvalidArgument(f"part {part!r}: one of {', '.join(HOLDER_PARTS)}")
    who = "*" if holder is None else check_name(holder, "holder")
    return control_key(robot, f"{who}/{part}")


def holder_of(key: object, robot: str, part: str) -> str:
    """The holder a key of :func:`holder_key` names: the key chunk the router checked
    under an ACL. :class:`ProtocolError` for any other key (a wildcard, a wrong part)."""
    parts = str(key).split("/")
    if len(parts) != 5 or parts[:3] != [ROOT, robot, "@control"] or parts[4] != part:
        raise ProtocolError(f"{str(key)[:120]!r} is not a {part} key of {robot}")
    try:
        return check_name(parts[3], "holder")
    except InvalidArgument as exc:
        raise ProtocolError(str(exc)) from None


def encode(data: dict[str, Any]) -> bytes:
    """``data`` as compact UTF-8 JSON, NaN and infinities written as null."""
    return json.dumps(_finite(data), separators=(",", ":"), allow_nan=False).encode()


def decode(payload: bytes, what: str) -> dict[str, Any]:
    """A JSON object from ``payload`` (at most :data:`MAX_PAYLOAD` bytes, finite numbers,
    bounded nesting: :func:`robocli.zenoh.payload.decode_object`), else
    :class:`ProtocolError` naming ``what``."""
    return decode_object(payload, what, MAX_PAYLOAD)


def number(data: dict[str, Any], name: str, what: str) -> float:
    """``data[name]`` as a finite float, else :class:`ProtocolError`."""
    value = data.get(name)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ProtocolError(f"{what}: {name!r} must be a number, not {value!r}")
    if not math.isfinite(value):
        raise ProtocolError(f"{what}: {name!r} must be finite, not {value!r}")
    return float(value)


def text(data: dict[str, Any], name: str, what: str) -> str:
    """``data[name]`` as a string, else :class:`ProtocolError`."""
    value = data.get(name)
    if not isinstance(value, str):
        raise ProtocolError(f"{what}: {name!r} must be a string, not {value!r}")
    return value


def put(publisher: Any, data: dict[str, Any]) -> None:
    """Put ``data`` as JSON. A session that is closing refuses it (``zenoh.ZError``): that is
    logged, never raised, since the loops that put end with the session. Any other error (a
    value JSON cannot take) is a bug, and raises."""
    import zenoh  # the bridges run only with the zenoh extra; loaded already

    payload = encode(data)
    try:
        publisher.put(payload)
    except zenoh.ZError:
        logging.getLogger(__name__).debug("put failed", exc_info=True)


def reply(query: Any, data: dict[str, Any], *, error: bool = False) -> None:
    """Answer ``query`` with ``data`` as JSON (an error reply when ``error``); a querier
    that is gone is logged, never raised."""
    try:
        if error:
            query.reply_err(encode(data), encoding=JSON_ENCODING)
        else:
            query.reply(query.key_expr, encode(data), encoding=JSON_ENCODING)
    except Exception:
        logging.getLogger(__name__).debug("reply failed", exc_info=True)


def _finite(data: Any) -> Any:
    if isinstance(data, float):
        return data if math.isfinite(data) else None
    if isinstance(data, dict):
        return {k: _finite(v) for k, v in data.items()}
    if isinstance(data, (list, tuple)):
        return [_finite(v) for v in data]
    return data


__all__ = ["HOLDER_PARTS", "JSON_ENCODING", "MAX_PAYLOAD", "control_key", "decode", "encode",
           "holder_key", "holder_of", "number", "reply", "text", "undeclare"]  # fmt: skip
