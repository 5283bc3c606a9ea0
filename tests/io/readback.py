"""Reading recordings back with the ``mcap`` package's own readers (not robocli's), and
checking JSON messages against the schema their channel names."""

from __future__ import annotations

import base64
import binascii
import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from mcap.reader import make_reader
from mcap.stream_reader import StreamReader

WAIT = 30.0  #: bounds a failure only: every wait polls for an event


def wait_for(pred: Callable[[], Any], timeout: float = WAIT, what: str = "condition") -> Any:
    """Poll ``pred`` until it is truthy; fail after ``timeout`` s."""
    end = time.monotonic() + timeout
    while True:
        value = pred()
        if value:
            return value
        if time.monotonic() > end:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.01)


def messages(path: Path, topics: list[str] | None = None) -> list[tuple[Any, Any, Any]]:
    """(schema, channel, message) of a finished recording, through its summary."""
    with path.open("rb") as f:
        reader = make_reader(f)
        assert reader.get_summary() is not None, "no summary section"
        return list(reader.iter_messages(topics=topics))


def by_topic(path: Path) -> dict[str, list[tuple[Any, Any, Any]]]:
    out: dict[str, list[tuple[Any, Any, Any]]] = {}
    for item in messages(path):
        out.setdefault(item[1].topic, []).append(item)
    return out


def stream_messages(path: Path) -> tuple[list[Any], bool]:
    """Every message record of a possibly truncated file, read in order with the ``mcap``
    stream reader until its first incomplete record: (messages, cut short)."""
    from mcap.records import Message

    out: list[Any] = []
    with path.open("rb") as f:
        records = StreamReader(f).records
        while True:
            try:
                record = next(records)
            except StopIteration:
                return out, False
            except Exception:  # noqa: BLE001 - whatever the reader raises at a cut
                return out, True
            if isinstance(record, Message):
                out.append(record)


def conforms(value: Any, schema: dict[str, Any], where: str = "$") -> None:
    """Assert ``value`` fits ``schema`` (the JSON Schema keywords robocli's schemas use)."""
    kinds = schema.get("type")
    if kinds is not None:
        allowed = kinds if isinstance(kinds, list) else [kinds]
        checks = {
            "object": lambda v: isinstance(v, dict), "array": lambda v: isinstance(v, list),
            "string": lambda v: isinstance(v, str), "boolean": lambda v: isinstance(v, bool),
            "integer": lambda v: isinstance(v, int) and not isinstance(v, bool),
            "number": lambda v: isinstance(v, (int, float)) and not isinstance(v, bool),
            "null": lambda v: v is None,
        }  # fmt: skip
        assert any(checks[k](value) for k in allowed), f"{where}: {value!r} is not {kinds}"
    if isinstance(value, dict):
        for key in schema.get("required", []):
            assert key in value, f"{where}: missing {key!r}"
        for key, sub in schema.get("properties", {}).items():
            if key in value:
                conforms(value[key], sub, f"{where}.{key}")
    if isinstance(value, list) and "items" in schema:
        for i, item in enumerate(value):
            conforms(item, schema["items"], f"{where}[{i}]")
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        assert schema.get("minimum", value) <= value <= schema.get("maximum", value), where
    if schema.get("contentEncoding") == "base64":
        try:
            base64.b64decode(value, validate=True)
        except binascii.Error as exc:
            raise AssertionError(f"{where}: not base64 ({exc})") from None


def decoded(item: tuple[Any, Any, Any]) -> Any:
    """The JSON of one (schema, channel, message), checked against the schema it names."""
    schema, channel, message = item
    assert channel.message_encoding == "json"
    assert schema is not None and schema.encoding == "jsonschema"
    data = json.loads(message.data)
    conforms(data, json.loads(schema.data))
    return data
