"""Raw links and the JSON encoding the device channels share (see :mod:`.sources`)."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from robocli.io.record.recorder import Recorder

__all__ = ["RAW_ENCODING", "RawLink", "json_text", "new_link", "raw_link"]

#: Message encoding of the raw-bytes channels: each message is one whole frame as it went
#: over the link (framing and checksum included), in the protocol named by the channel's
#: ``protocol`` metadata.
RAW_ENCODING = "robocli.raw"

_ENCODE = json.JSONEncoder(separators=(",", ":"), allow_nan=False).encode


def json_text(message: Any) -> str:
    """Compact JSON of ``message``; NaN and infinities (no reading) become null."""
    try:
        return _ENCODE(message)
    except ValueError:
        return _ENCODE(_finite(message))


def _finite(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value




class RawLink:
    """A listener ``(direction, payload, t)`` writing every frame of one link into its raw
    channels, then handing the payload to :attr:`decoder` (writer thread). ``reframe``
    rebuilds the whole frame from what the device's listener gets (the Pioneer's listeners
    see payloads without sync bytes and checksum)."""

    def __init__(self, rec: Recorder, name: str, protocol: str, *,
                 reframe: Callable[[bytes], bytes] | None = None, port: str | None = None,
                 **metadata: str) -> None:  # fmt: skip
        self.rec, self.name, self.protocol, self.port = rec, name, protocol, port
        self._reframe = reframe
        self._metadata = {"protocol": protocol, "link": name, **metadata}
        if port is not None:
            self._metadata["port"] = port
        self._cids: dict[str, int] = {}
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
            cid = self.rec.channel(f"/{self.name}/raw/{part}", None, encoding=RAW_ENCODING,
                                   metadata={**self._metadata, "direction": direction})  # fmt: skip
            self._cids[direction] = cid
        ns = self.rec.log_ns(t)
        self.rec.write(cid, self._reframe(payload) if self._reframe else payload, ns)
        if self.decoder is not None:
            self.decoder(direction, payload, ns)


def raw_link(rec: Recorder, name: str, protocol: str, **metadata: str) -> RawLink:
    """A new raw link of ``rec`` named ``name`` (``name2``... when taken): see
    :meth:`Recorder.listener`."""
    return new_link(rec, rec.unique_name(name), protocol, **metadata)


def new_link(rec: Recorder, name: str, protocol: str, **metadata: str) -> RawLink:
    """A raw link under ``name`` (reserved with :meth:`Recorder.unique_name`)."""
    reframe: Callable[[bytes], bytes] | None = None
    if protocol == "arcos":
        from robocli.protocols.arcos import frame

        reframe = frame
    link = RawLink(rec, name, protocol, reframe=reframe, **metadata)
    rec.links[name] = link
    return link
