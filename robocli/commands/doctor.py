"""``robocli doctor``: a thin layer over :func:`robocli.diagnostics.diagnose`."""

from __future__ import annotations

import typer

from robocli.commands._common import echo_lines, print_json, rounded
from robocli.commands._options import json_option
from robocli.defaults import (
    ARM_ENV,
    ARM_HOST,
    ARM_MOTION_PORT,
    ARM_STATE_PORT,
    HUB_ADDRESS,
    HUB_ENV,
    PIONEER_ENV,
    PIONEER_URL,
)


def doctor(
    json_out: bool = json_option(),
    timeout: float = typer.Option(
        1.0, "--timeout", min=0.05, max=10.0, help="Seconds each probe may wait."
    ),
    pioneer: str | None = typer.Option(
        None,
        "--pioneer",
        metavar="URL",
        help=f"Pioneer to probe (default ${PIONEER_ENV}, else {PIONEER_URL}).",
    ),
    arm: str | None = typer.Option(
        None, "--arm", metavar="URL", help=f"Arm to probe (default ${ARM_ENV}, else {ARM_HOST})."
    ),
    hub: str | None = typer.Option(
        None,
        "--hub",
        metavar="URL",
        help=f"Hub to probe (default ${HUB_ENV}, else {HUB_ADDRESS}).",
    ),
    motion_port: int = typer.Option(
        ARM_MOTION_PORT, "--motion-port", min=1, max=65535, help="The arm's motion port."
    ),
    state_port: int = typer.Option(
        ARM_STATE_PORT, "--state-port", min=1, max=65535, help="The arm's state port."
    ),
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
