"""Packets as ``robocli dump`` shows them, for a notebook too: one text line per packet (raw
units, long lists summed up, cut at :data:`LINE_MAX` characters unless ``full``) and one
JSON-ready record per packet (``t`` in Unix time when known, ``t_rel`` since the start,
``dir`` as capture files say it). Nothing here prints."""

from __future__ import annotations

import json
from typing import Any

from robocli.analysis.packets import Packet, PacketLog
from robocli.io.jsonlines import rounded

__all__ = ["ARROWS", "LINE_MAX", "arm_line", "arm_record", "ellipsis", "hub_line",
           "hub_record", "laser_lines", "pioneer_line", "pioneer_record"]  # fmt: skip

#: Longest text line of a packet unless ``full`` (the rest is cut with an ellipsis).
LINE_MAX = 160
ARROWS = {"tx": "->", "rx": "<-"}
#: Short names of Simple Message fields in text lines (JSON keeps the protocol's names).
_SHORT = {"drives_powered": "powered", "e_stopped": "estop", "error_code": "code",
          "in_error": "error", "in_motion": "moving", "motion_possible": "possible",
          "valid_fields": "valid", "sequence": "seq", "robot_id": "robot"}  # fmt: skip


def ellipsis(encoding: str | None) -> str:
    """``…`` where ``encoding`` (an output's) can encode it, else ``...`` (a latin-1 or ASCII
    terminal, ``PYTHONIOENCODING=ascii``)."""
    try:
        "\u2026".encode(encoding or "ascii")
    except (UnicodeEncodeError, LookupError):
        return "..."
    return "\u2026"


def _cut(line: str, mark: str) -> str:
    return line if len(line) <= LINE_MAX else line[: LINE_MAX - len(mark)] + mark


def _stamp(p: Packet) -> str:
    return f"{p.t:9.3f} " if p.t is not None else ""


def pioneer_line(p: Packet, full: bool = False, mark: str = "\u2026") -> str:
    """An ARCOS packet: time, direction, name and fields (sonar and laser readings as how
    many and the nearest unless ``full``)."""
    text = " ".join(f"{k}={_short(v, full)}" for k, v in p.fields.items())
    line = f"{_stamp(p)}{ARROWS.get(p.direction, '  ')} {p.name:<12} {text}".rstrip()
    return line if full else _cut(line, mark)


def pioneer_record(log: PacketLog, p: Packet) -> dict[str, Any]:
    out: dict[str, Any] = rounded({**log.stamp(p.t), "dir": p.wire_dir, "type": p.type,
                                   "name": p.name, "fields": p.fields})  # fmt: skip
    return out


def arm_line(p: Packet, mark: str = "\u2026") -> str:
    """A Simple Message: time, port, direction, name and fields (short names)."""
    text = " ".join(f"{_SHORT.get(k, k)}={_short_sm(v)}" for k, v in p.fields.items())
    line = f"{_stamp(p)}{p.port or '-':<6} {ARROWS.get(p.direction, '  ')} {p.name:<22} {text}"
    return _cut(line.rstrip(), mark)


def arm_record(log: PacketLog, p: Packet, hex_out: bool = False) -> dict[str, Any]:
    hexed = {"hex": p.frame.hex()} if hex_out else {}
    out: dict[str, Any] = rounded({**log.stamp(p.t), "port": p.port, "dir": p.wire_dir,
                                   "name": p.name, "fields": p.fields, **hexed})  # fmt: skip
    return out


def hub_line(p: Packet) -> str:
    """A ros4mat message: time, direction, name and fields."""
    stamp = f"{p.t:10.6f}" if p.t is not None else f"{'-':>10}"
    text = " ".join(f"{k}={v}" for k, v in p.fields.items())
    return f"{stamp} {ARROWS[p.direction]} {p.name:<14} {text}"


def hub_record(log: PacketLog, p: Packet, hex_out: bool = False) -> str:
    """A ros4mat message as one line of JSON: its fields beside the stamp (which a field of
    the message never hides)."""
    record = {**log.stamp(p.t), "dir": p.wire_dir, "name": p.name, **p.fields}
    record.update(rounded(log.stamp(p.t)))
    return json.dumps({**record, **({"hex": p.frame.hex()} if hex_out else {})}, default=str)


def laser_lines(log: PacketLog, p: Packet, t0: list[float], json_out: bool) -> list[Any]:
    """Each line of a SCIP block, as text or as a record: ``t`` Unix time (None when
    unknown), ``t_rel`` seconds since the first line (``t0``: the first line's time, set by
    the first call)."""
    t = p.t or 0.0
    if not t0:
        t0.append(t)
    rel = t - t0[0]
    if not json_out:
        return [f"{rel:10.6f} {ARROWS[p.direction]} {line.text[:70]:<70} {line.what}"
                for line in p.lines]  # fmt: skip
    unix = None if log.epoch is None else round(t + log.epoch, 6)
    return [{"t": unix, "t_rel": round(rel, 6), "dir": p.wire_dir, "line": line.text,
             "what": line.what} for line in p.lines]  # fmt: skip


def _short(value: Any, full: bool) -> str:
    """A field's value in a text line: unless ``full``, long lists (sonar pairs, laser
    readings) as how many and the nearest."""
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, list) and value and isinstance(value[0], (tuple, dict)):
        if full:
            return "[" + ",".join(_short(v, full) for v in value) + "]"
        ranges = [v["range"] if isinstance(v, dict) else v[-1] for v in value]
        return f"{len(value)}(min {min(ranges)})"  # how many, the nearest
    if isinstance(value, tuple):
        return ":".join(map(str, value))
    if isinstance(value, list) and len(value) > 8 and not full:
        return f"{len(value)}(min {min(value)})"  # laser ranges: how many, the nearest
    if isinstance(value, dict):
        return "{" + ",".join(f"{k}={_short(v, full)}" for k, v in value.items()
                              if v is not None) + "}"  # fmt: skip
    return str(value)


def _short_sm(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, list):
        return "[" + ",".join(_short_sm(v) for v in value) + "]"
    return str(value)
