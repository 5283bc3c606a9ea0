"""``robocli doctor``: a thin layer over :func:`robocli.diagnostics.diagnose`."""

from __future__ import annotations

from typing import Any

import typer

from robocli.commands._common import print_json, rounded
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

    report = diagnose(pioneer=pioneer, arm=arm, hub=hub, motion_port=motion_port,
                      state_port=state_port, timeout=timeout)  # fmt: skip
    if json_out:
        print_json(rounded(report, 3, {"t": 6}))
        return
    _print(report)


def _print(r: dict[str, Any]) -> None:
    v = r["versions"]
    typer.echo(f"robocli {v['robocli']}, {v['implementation']} {v['python']} on {v['platform']}")
    typer.echo("packages   " + ", ".join(f"{k} {x or 'MISSING'}" for k, x in v["packages"].items()))
    core = r["c_core"]
    typer.echo(f"C core     {'loaded from ' + core['path'] if core['loaded'] else core['error']}")
    extras = [f"{name} {'yes' if e['installed'] else 'no'}" for name, e in r["extras"].items()]
    typer.echo("extras     " + (", ".join(extras) or "unknown (robocli-robots is not installed)"))
    serial = r["serial"]
    if serial["error"]:
        typer.echo(f"serial     cannot list ports: {serial['error']}")
    elif not serial["ports"]:
        typer.echo("serial     no ports found (is the USB-serial adapter plugged in?)")
    for p in serial["ports"]:
        access = "you may open it" if p["may_open"] else "you may NOT open it"
        typer.echo(f"serial     {p['device']}  {p['description']}  ({access})")
    group = serial.get("group")
    if group and group["exists"]:
        state = "member" if group["active"] else "member after a new login" if group[
            "member"] else "not a member"  # fmt: skip
        typer.echo(f"group      {group['name']}: {state}"
                   + (f"; {group['advice']}" if group["advice"] else ""))  # fmt: skip
    for name, a in r["addresses"].items():
        source = {"env": f"${a['env']}", "given": "given"}.get(a["source"], "default")
        answer = {True: "answers", False: "no answer", None: "not probed"}[a["answers"]]
        typer.echo(f"{name:<11}{a['address']} ({source}): {answer}: {a['detail']}")
    for problem in r["problems"]:
        typer.echo(f"PROBLEM    {problem}")
