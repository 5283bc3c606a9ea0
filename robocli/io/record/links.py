"""Raw links and the JSON encoding the device channels share (see :mod:`.sources`)."""

from __future__ import annotations

import base64
import json
import logging
import math
from collections.abc import Callable, Iterable
from typing import Any, Protocol

from robocli.ros2.types import RAW_FRAME
from robocli.ros2.types import RAW_SCHEMA as _RAW_SCHEMA
from robocli.sink import SinkBase

__all__ = [
    "RAW_ENCODING",
    "RAW_SCHEMA",
    "ROS2_RAW_TYPE",
    "RawLink",
    "Sink",
    "SinkBase",
    "TopicDecoder",
    "is_raw",
    "json_text",
    "new_link",
    "raw_link",
    "record_scans",
]

log = logging.getLogger("robocli.io.record")

#: Schema of the raw channels (message encoding ``json``, schema encoding ``jsonschema``,
#: as every channel: a viewer shows them): each message is one whole frame as it went over
#: the link (framing and checksum included), base64 in its ``data``, with its ``link``,
#: ``protocol`` (also the channel's metadata, as ``direction`` and ``port``).
RAW_SCHEMA = _RAW_SCHEMA
#: Message encoding of the raw channels of recordings made before :data:`RAW_SCHEMA`: each
#: message the frame's bytes themselves, without a schema (no viewer knows the encoding).
#: Read, never written.
RAW_ENCODING = "robocli.raw"


#: The raw channels' type in a ROS 2 bag (CDR, see :mod:`robocli.ros2.types`).
ROS2_RAW_TYPE = RAW_FRAME


def is_raw(encoding: str, schema: str) -> bool:
    """Whether a channel of ``encoding`` and ``schema`` (name) is a raw channel: robocli's
    JSON, its older bytes, or a ROS 2 bag's ``robocli_msgs/msg/RawFrame``."""
    return schema == RAW_SCHEMA or encoding == RAW_ENCODING or schema == ROS2_RAW_TYPE


class Sink(Protocol):
    """What a device's recording writes into (:class:`~robocli.io.record.Recorder` is one):
    named links, a queue to its writer thread, and channels and messages on that thread."""

    links: dict[str, Any]

    def log_ns(self, t_monotonic: float) -> int:
        """A monotonic time (s) in Unix-epoch ns."""
        ...

    def unique_name(self, base: str) -> str:
        """``base``, or ``base2``, ``base3``... the first not taken yet."""
        ...

    def on_close(self, detach: Callable[[], None]) -> None:
        """Call ``detach`` when the recording closes."""
        ...

    def put(self, handler: Callable[..., None], args: tuple[Any, ...], size: int = 64) -> bool:
        """Queue ``handler(*args)`` for the writer thread; never blocks."""
        ...

    def channel(self, topic: str, schema: str | None, *, encoding: str = "json",
                metadata: dict[str, str] | None = None) -> int:  # fmt: skip
        """The id of ``topic``'s channel (writer thread only)."""
        ...

    def write(self, cid: int, data: bytes, log_ns: int, publish_ns: int | None = None) -> None:
        """Add one message to channel ``cid`` (writer thread only)."""
        ...


_ENCODE = json.JSONEncoder(separators=(",", ":"), allow_nan=False).encode


def json_text(message: Any) -> str:
    """Compact JSON of ``message`` (a dict). A number without a value (NaN, an infinity:
    no reading) is left out, never written as null, which Foxglove's schemas cannot say
    (:mod:`robocli.io.schemas`): a field holding one is omitted, and so is a list holding
    one (a list with a hole would shift the indexes after it)."""
    try:
        return _ENCODE(message)
    except ValueError:
        return _ENCODE(_finite(message))


_MISSING = object()


def _finite(value: Any) -> Any:
    """``value`` without its non-finite numbers (see :func:`json_text`); ``_MISSING`` for
    a number or a list that has none left to say."""
    if isinstance(value, float):
        return value if math.isfinite(value) else _MISSING
    if isinstance(value, dict):
        out = {k: _finite(v) for k, v in value.items()}
        return {k: v for k, v in out.items() if v is not _MISSING}
    if isinstance(value, (list, tuple)):
        items = [_finite(v) for v in value]
        return _MISSING if any(v is _MISSING for v in items) else items
    return value


class RawLink:
    """A listener ``(direction, payload, t)`` writing every frame of one link into its raw
    channels, then handing the payload to :attr:`decoder` (writer thread). ``reframe``
    rebuilds the whole frame from what the device's listener gets (the Pioneer's listeners
    see payloads without sync bytes and checksum)."""

    def __init__(self, rec: Sink, name: str, protocol: str, *,
                 reframe: Callable[[bytes], bytes] | None = None, port: str | None = None,
                 **metadata: str) -> None:  # fmt: skip
        self.rec, self.name, self.protocol, self.port = rec, name, protocol, port
        self._reframe = reframe
        self._metadata = {"protocol": protocol, "link": name, **metadata}
        if port is not None:
            self._metadata["port"] = port
        self._cids: dict[str, int] = {}
        self._heads: dict[str, bytes] = {}  # the JSON between the stamp and the bytes
        #: called as ``decoder(direction, payload, log_ns)`` after the raw message is written
        self.decoder: Callable[[str, bytes, int], None] | None = None
        self._put = rec.put
        self._handle_ref = self._handle

    def __call__(self, direction: str, payload: bytes, t: float) -> None:
        self._put(self._handle_ref, (direction, payload, t), len(payload))

    def _handle(self, direction: str, payload: bytes, t: float) -> None:
        cid = self._cids.get(direction)
        if cid is None:
            part = f"{self.port}/{direction}" if self.port else direction
            cid = self.rec.channel(f"/{self.name}/raw/{part}", RAW_SCHEMA,
                                   metadata={**self._metadata, "direction": direction})  # fmt: skip
            self._cids[direction] = cid
            fields = {"link": self.name, "protocol": self.protocol, "direction": direction,
                      "port": self.port or ""}  # fmt: skip
            self._heads[direction] = f',{json_text(fields)[1:-1]},"data":"'.encode()
        ns = self.rec.log_ns(t)
        frame = self._reframe(payload) if self._reframe else payload
        sec, nsec = divmod(ns, 1_000_000_000)
        self.rec.write(cid, b'{"timestamp":{"sec":%d,"nsec":%d}%s%s"}' % (
            sec, nsec, self._heads[direction], base64.b64encode(frame)), ns)  # fmt: skip
        if self.decoder is not None:
            self.decoder(direction, payload, ns)


class TopicDecoder:
    """A decoder's topics (``/NAME/KEY`` for each key) and their channels in ``rec``, each
    made on first use by :meth:`_cid` (writer thread)."""

    def __init__(self, rec: Sink, name: str, keys: Iterable[str]) -> None:
        self.rec = rec
        self.topics = {k: f"/{name}/{k}" for k in keys}
        self._cids: dict[str, int] = {}

    def _cid(self, key: str, schema: str) -> int:
        cid = self._cids.get(key)
        if cid is None:
            cid = self._cids[key] = self.rec.channel(self.topics[key], schema)
        return cid


def record_scans(rec: Sink, device: Any, kind: str, on_scan: Callable[[Any], None]) -> None:
    """Hand every scan of ``device``'s listeners of ``kind`` to ``on_scan`` on ``rec``'s
    writer thread, until ``rec`` closes."""
    put = rec.put

    def listener(scan: Any) -> None:
        put(on_scan, (scan,), 8 * len(scan.ranges))

    device.add_listener(listener, kind=kind)
    rec.on_close(lambda: device.remove_listener(listener, kind=kind))


def raw_link(rec: Sink, name: str, protocol: str, **metadata: str) -> RawLink:
    """A new raw link of ``rec`` named ``name`` (``name2``... when taken): see
    :meth:`Sink.listener`."""
    return new_link(rec, rec.unique_name(name), protocol, **metadata)


def new_link(rec: Sink, name: str, protocol: str, **metadata: str) -> RawLink:
    """A raw link under ``name`` (reserved with :meth:`Sink.unique_name`)."""
    reframe: Callable[[bytes], bytes] | None = None
    if protocol == "arcos":
        from robocli.protocols.arcos import frame

        reframe = frame
    link = RawLink(rec, name, protocol, reframe=reframe, **metadata)
    rec.links[name] = link
    return link
