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
``robocli/<robot>/@control``                queryable: acquire, release, who holds the robot
``robocli/<robot>/@control/holder/<name>``  liveliness token of the controller ``<name>``
                                            holding the robot
``robocli/<robot>/@control/event``          put per control event (granted, refused, stopped,
                                            released, fault)
``robocli/<robot>/@control/velocity``       put: a Pioneer's velocity set-point (holder only)
``robocli/<robot>/@control/trajectory``     queryable: an arm's trajectory upload (holder only)
==========================================  ===================================================

Every payload is UTF-8 JSON with the Zenoh encoding ``application/json``, in SI units, ``t``
in Unix epoch seconds: any Zenoh program can watch and drive a robot without robocli.
"""

from __future__ import annotations

import json
import logging
import math
from typing import Any

from robocli.errors import ProtocolError
from robocli.zenoh.keys import ROOT, check_name

JSON_ENCODING = "application/json"
#: The largest command or control payload a bridge decodes (bytes): a trajectory of a few
#: thousand points fits
MAX_PAYLOAD = 4 << 20


def control_key(robot: str, part: str | None = None) -> str:
    """``robocli/<robot>/@control`` (with ``part``: ``.../@control/<part>``)."""
    base = f"{ROOT}/{check_name(robot)}/@control"
    return base if part is None else f"{base}/{part}"


def holder_key(robot: str, holder: str | None = None) -> str:
    """The liveliness token of ``holder`` controlling ``robot`` (None: ``*``, any holder)."""
    return control_key(robot, "holder/" + ("*" if holder is None else check_name(holder, "holder")))


def encode(data: dict[str, Any]) -> bytes:
    """``data`` as compact UTF-8 JSON, NaN and infinities written as null."""
    return json.dumps(_finite(data), separators=(",", ":"), allow_nan=False).encode()


def decode(payload: bytes, what: str) -> dict[str, Any]:
    """A JSON object from ``payload`` (at most :data:`MAX_PAYLOAD` bytes), else
    :class:`ProtocolError` naming ``what``."""
    if len(payload) > MAX_PAYLOAD:
        raise ProtocolError(f"{what}: {len(payload)} bytes, more than {MAX_PAYLOAD}")
    try:
        data = json.loads(payload.decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise ProtocolError(f"{what}: not UTF-8 JSON ({exc})") from None
    if not isinstance(data, dict):
        raise ProtocolError(f"{what}: a JSON object was expected, not {type(data).__name__}")
    return data


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


def undeclare(entity: Any) -> None:
    """Undeclare a Zenoh entity; one of a session already closed is left (logged)."""
    import zenoh

    try:
        entity.undeclare()
    except zenoh.ZError:
        logging.getLogger(__name__).debug("undeclare failed", exc_info=True)


def _finite(data: Any) -> Any:
    if isinstance(data, float):
        return data if math.isfinite(data) else None
    if isinstance(data, dict):
        return {k: _finite(v) for k, v in data.items()}
    if isinstance(data, (list, tuple)):
        return [_finite(v) for v in data]
    return data


__all__ = ["JSON_ENCODING", "MAX_PAYLOAD", "control_key", "decode", "encode", "holder_key",
           "number", "text"]  # fmt: skip
