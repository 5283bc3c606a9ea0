"""Captured traffic, named and decoded: what ``robocli dump`` shows, as a library.

Each protocol has a decoder that names a frame and decodes its fields into a
:class:`~robocli.analysis.packets.Packet` (:mod:`~robocli.analysis.arcos` for a Pioneer,
:mod:`~robocli.analysis.simple_message` for an arm, :mod:`~robocli.analysis.ros4mat` for the
hub, :mod:`~robocli.analysis.scip` for a Hokuyo laser); :mod:`~robocli.analysis.sessions`
reads captures and live sessions into packets in time order, and
:mod:`~robocli.analysis.proxy` relays other programs' sessions to record them. Nothing here
prints: packets are returned or handed to a callback, and a notebook renders them as it likes::

    from robocli.analysis import read_packets
    for packet in read_packets("session.jsonl", "arcos"):
        print(packet.t, packet.direction, packet.name, packet.fields)
"""

from __future__ import annotations

import importlib
from typing import Any

#: Public name -> the module that defines it (loaded on first use: ``robocli dump`` stays
#: quick to start, and a decoder does not load the others).
_WHERE = {
    "Packet": "packets", "PacketLog": "packets",
    "ArcosDecoder": "arcos", "guess_direction": "arcos",
    "SimpleMessageDecoder": "simple_message", "describe_message": "simple_message",
    "DumpProxy": "ros4mat",
    "Line": "scip", "ScipCapture": "scip", "describe_reply": "scip", "describe_request": "scip",
    "RecordingProxy": "proxy", "Message": "proxy",
    "decoder": "sessions", "read_packets": "sessions", "replay_capture": "sessions",
}  # fmt: skip

__all__ = sorted(_WHERE)


def __getattr__(name: str) -> Any:
    if name not in _WHERE:
        raise AttributeError(f"module 'robocli.analysis' has no attribute {name!r}")
    return getattr(importlib.import_module(f"robocli.analysis.{_WHERE[name]}"), name)
