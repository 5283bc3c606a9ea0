"""A hub as ``connect hub`` shows it: the survey of :func:`robocli.devices.hub.tools.survey`
(its sensors and their rates, round trip, clock offset) as lines of text."""

from __future__ import annotations

from typing import Any

__all__ = ["survey_lines"]


def _ms(value: float | None) -> str:
    """``0.123 ms``, or ``-`` before any data reply (nothing running to pull)."""
    return "-" if value is None else f"{value} ms"


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
