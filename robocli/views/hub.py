"""A hub as ``connect hub`` shows it: the survey of :func:`robocli.devices.hub.tools.survey`
(its sensors and their rates, round trip, clock offset) as lines of text."""

from __future__ import annotations

import io
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import numpy as np

__all__ = ["header_text", "rows_text", "survey_lines"]


def _ms(value: float | None) -> str:
    """``0.123 ms``, or ``-`` before any data reply (nothing running to pull)."""
    return "-" if value is None else f"{value} ms"


def header_text(fmt: str, cols: tuple[str, ...]) -> str:
    """The line before ``subscribe``'s samples as ``fmt`` (csv, table, jsonl: none) shows them."""
    if fmt == "csv":
        return ",".join(cols) + "\n"
    return "".join(f"{c:>18}" for c in cols) + "\n" if fmt == "table" else ""


def rows_text(fmt: str, cols: tuple[str, ...], rows: np.ndarray[Any, Any]) -> str:
    """Samples (a row each: time, then ``cols[1:]``) as CSV, JSON Lines (``jsonl``, SI) or
    aligned text (``table``), a line each."""
    import numpy as np

    buf = io.StringIO()
    if fmt == "csv":
        np.savetxt(buf, rows, fmt=["%.6f"] + ["%.7g"] * (rows.shape[1] - 1), delimiter=",")
    elif fmt == "jsonl":
        from robocli.devices.hub.streams import json_rows

        buf.write(json_rows(cols, rows))
    else:
        np.savetxt(buf, rows, fmt=["%18.6f"] + ["%18.7g"] * (rows.shape[1] - 1), delimiter="")
    return buf.getvalue()


def survey_lines(info: dict[str, Any]) -> list[str]:
    """The hub, its protocol, our client id, round trip and clock offset; then each sensor,
    running at its rate or idle (and why)."""
    out = [f"hub {info['hub']}  ros4mat v{info['protocol_version']}  client id "
           f"{info['client_id']} (clients seen)  rtt {_ms(info['rtt_ms'])}  "
           f"clock offset {_ms(info['clock_offset_ms'])}"]  # fmt: skip
    for name, s in info["sensors"].items():
        out.append(f"  {name:<14} running  {s['rate_hz']:>8} Hz" if s["active"]
                   else f"  {name:<14} idle     ({s['reason']})")  # fmt: skip
    return out
