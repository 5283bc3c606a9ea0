"""Reading recordings back with the ``mcap`` package's own readers (not robocli's), and
checking JSON messages as a viewer takes them: against the schema their channel names
(jsonschema), that schema against the subset Foxglove reads, and a message on a Foxglove
well-known schema against Foxglove's own (``@foxglove/schemas``, vendored)."""

from __future__ import annotations

import base64
import binascii
import json
from pathlib import Path
from typing import Any

from mcap.reader import make_reader
from mcap.stream_reader import StreamReader

from tests.paths import DATA

WAIT = 30.0  #: bounds a failure only: every wait polls for an event


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
            except Exception:
                return out, True
            if isinstance(record, Message):
                out.append(record)


#: Foxglove's own JSON schemas of the well-known schemas robocli writes (@foxglove/schemas
#: 2.1.0, vendored: tests/data/foxglove_schemas/README.md), by schema name.
FOXGLOVE_SCHEMAS: dict[str, dict[str, Any]] = {
    p.stem: json.loads(p.read_text())
    for p in (DATA / "foxglove_schemas").glob("foxglove.*.json")
}
#: What the subset Foxglove and Lichtblick read has no use for: a field has one type.
_UNIONS = ("anyOf", "oneOf", "allOf", "not", "$ref", "if", "patternProperties")
_SCALARS = ("string", "number", "integer", "boolean")


def foxglove_subset(schema: Any, where: str = "$") -> None:
    """Assert ``schema`` is inside the JSON-schema subset Foxglove's viewers read (the rules
    of Lichtblick's ``parseJsonSchema``, the viewer that refused robocli's channels): an
    object at the root, whose fields each have one ``type`` string (not a list, not
    ``null``) among object (with ``properties``), array, string, number, integer, boolean;
    a string's ``contentEncoding`` base64 or none; an array's ``items`` one of those but
    an array, and a string item without ``contentEncoding``; no union keyword;
    recursively."""
    assert isinstance(schema, dict) and schema.get("type") == "object", \
        f"{where}: the root is not an object"  # fmt: skip
    _field(schema, where, item=False)


def _field(schema: Any, where: str, item: bool) -> None:
    assert isinstance(schema, dict), f"{where}: not a schema object"
    kind = schema.get("type")
    assert isinstance(kind, str), f"{where}: type {kind!r} is not one type string"
    allowed = ("object", *_SCALARS) if item else ("object", "array", *_SCALARS)
    assert kind in allowed, f"{where}: type {kind!r} (not one of {', '.join(allowed)})"
    for key in _UNIONS:
        assert key not in schema, f"{where}: {key} (a union)"
    if kind == "string":
        encoding = schema.get("contentEncoding")
        assert encoding in ((None,) if item else (None, "base64")), \
            f"{where}: contentEncoding {encoding!r}"  # fmt: skip
    elif kind == "object":
        props = schema.get("properties")
        assert isinstance(props, dict) and props, f"{where}: an object without properties"
        for key, sub in props.items():
            _field(sub, f"{where}.{key}", item=False)
        assert set(schema.get("required", ())) <= set(props), f"{where}: required not a field"
    elif kind == "array":
        _field(schema.get("items"), f"{where}[]", item=True)


def conforms(value: Any, schema: dict[str, Any], where: str = "$") -> None:
    """Assert ``value`` is valid under ``schema`` (jsonschema), with every base64 string
    (``"contentEncoding": "base64"``) decodable."""
    import jsonschema

    error = jsonschema.exceptions.best_match(jsonschema.Draft7Validator(schema).iter_errors(value))
    assert error is None, f"{where}: {error.message} at {list(error.absolute_path)}"
    _base64(value, schema, where)


def _base64(value: Any, schema: dict[str, Any], where: str) -> None:
    if schema.get("contentEncoding") == "base64":
        try:
            base64.b64decode(value, validate=True)
        except binascii.Error as exc:
            raise AssertionError(f"{where}: not base64 ({exc})") from None
    if isinstance(value, dict):
        for key, sub in schema.get("properties", {}).items():
            if key in value:
                _base64(value[key], sub, f"{where}.{key}")
    if isinstance(value, list) and "items" in schema:
        for i, item in enumerate(value):
            _base64(item, schema["items"], f"{where}[{i}]")


def viewer_checked(name: str, schema: dict[str, Any], value: Any, where: str = "$") -> Any:
    """``value``, asserted valid under its channel's ``schema`` (named ``name``), that
    schema inside Foxglove's subset, and, on a Foxglove well-known schema, valid under
    Foxglove's own JSON schema of it."""
    foxglove_subset(schema, f"{where} schema {name}")
    conforms(value, schema, where)
    if name.startswith("foxglove."):
        assert name in FOXGLOVE_SCHEMAS, f"{name}: no vendored Foxglove schema"
        conforms(value, FOXGLOVE_SCHEMAS[name], f"{where} (Foxglove's {name})")
    return value


def decoded(item: tuple[Any, Any, Any]) -> Any:
    """The JSON of one (schema, channel, message), checked against the schema it names."""
    schema, channel, message = item
    assert channel.message_encoding == "json"
    assert schema is not None and schema.encoding == "jsonschema"
    return viewer_checked(
        schema.name, json.loads(schema.data), json.loads(message.data), channel.topic
    )


def frame_of(item: tuple[Any, Any, Any]) -> bytes:
    """The frame one raw channel's message carries (its base64 ``data``), the message
    checked as :func:`decoded` checks it."""
    return base64.b64decode(decoded(item)["data"], validate=True)
