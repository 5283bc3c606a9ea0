"""``robocli doctor``: a thin layer over :func:`robocli.diagnostics.diagnose`."""

from __future__ import annotations

from typing import Any

import typer

from robocli import defaults as d
from robocli.commands._common import echo_lines, print_json, rounded
from robocli.commands._options import device_option, json_option, timeout_option


def _probe(name: str, what: str, env: str, default: str) -> Any:
    return device_option(name, f"{what} to probe (default ${env}, else {default}).")


def _port(name: str, default: int) -> Any:
    return typer.Option(default, name, min=1, max=65535, help=f"The arm's {name[2:-5]} port.")


def doctor(
    json_out: bool = json_option(),
    timeout: float = timeout_option(1.0, "Seconds each probe may wait.", 0.05, 10.0),
    pioneer: str | None = _probe("--pioneer", "Pioneer", d.PIONEER_ENV, d.PIONEER_URL),
    arm: str | None = _probe("--arm", "Arm", d.ARM_ENV, d.ARM_HOST),
    hub: str | None = _probe("--hub", "Hub", d.HUB_ENV, d.HUB_ADDRESS),
    motion_port: int = _port("--motion-port", d.ARM_MOTION_PORT),
    state_port: int = _port("--state-port", d.ARM_STATE_PORT),
) -> None:
    """Check this machine for robocli: versions, the C core, serial ports and whether you
    may open them, optional extras, and whether the default addresses answer (each probe
    bounded by --timeout; nothing is moved)."""
    from robocli.diagnostics import diagnose
    from robocli.views.doctor import doctor_lines

    report = diagnose(pioneer=pioneer, arm=arm, hub=hub, motion_port=motion_port,
                      state_port=state_port, timeout=timeout)  # fmt: skip
    if json_out:
        print_json(rounded(report, 3, {"t": 6}))
        return
    echo_lines(doctor_lines(report))
