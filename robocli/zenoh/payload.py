"""The one decoder of the JSON payloads robocli takes from Zenoh (commands, control and
settings requests, replies), bounded so that no payload a stranger puts can raise anything
but :class:`~robocli.errors.ProtocolError` in a callback: a size cap, nesting too deep
for the parser (``[[[[...``, a ``RecursionError``) refused, numbers that are finite floats
or integers a float can hold (``1e400`` and a 400-digit integer would be an
``OverflowError`` later), no ``NaN``/``Infinity``, and a JSON object at the top.
"""

from __future__ import annotations

import json
import math
from typing import Any

from robocli.errors import ProtocolError

__all__ = ["MAX_INT", "decode_object"]

MAX_INT = 1 << 63  #: the largest integer magnitude taken


def _float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ProtocolError(f"number {text[:32]} is out of range")
    return value


def _int(text: str) -> int:
    if len(text) > 20:
        raise ProtocolError(f"integer {text[:32]}... is out of range")
    value = int(text)
    if abs(value) > MAX_INT:
        raise ProtocolError(f"integer {text} is out of range")
    return value


def _constant(text: str) -> Any:
    raise ProtocolError(f"{text} is not a number JSON allows")


def decode_object(payload: bytes, what: str, limit: int) -> dict[str, Any]:
    """The JSON object of ``payload`` (at most ``limit`` bytes), else :class:`ProtocolError`
    naming ``what`` (see the module)."""
    if len(payload) > limit:
        raise ProtocolError(f"{what}: {len(payload)} bytes, more than {limit}")
    try:
        data = json.loads(payload.decode("utf-8"), parse_float=_float, parse_int=_int,
                          parse_constant=_constant)  # fmt: skip
    except ProtocolError as exc:
        raise ProtocolError(f"{what}: {exc}") from None
    except RecursionError:
        raise ProtocolError(f"{what}: nested too deeply") from None
    except (UnicodeDecodeError, ValueError) as exc:
        raise ProtocolError(f"{what}: not UTF-8 JSON ({exc})") from None
    if not isinstance(data, dict):
        raise ProtocolError(f"{what}: a JSON object was expected, not {type(data).__name__}")
    return data
