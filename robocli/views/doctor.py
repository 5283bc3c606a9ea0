"""``robocli doctor``'s report (:func:`robocli.diagnostics.diagnose`) as lines of text: the
versions, the C core, the extras, the serial ports and whether you may open them, the
default addresses and whether they answer, and the problems found."""

from __future__ import annotations

from typing import Any

__all__ = ["doctor_lines"]


def doctor_lines(r: dict[str, Any]) -> list[str]:
    v, core, serial = r["versions"], r["c_core"], r["serial"]
    extras = [f"{name} {'yes' if e['installed'] else 'no'}" for name, e in r["extras"].items()]
    out = [
        f"robocli {v['robocli']}, {v['implementation']} {v['python']} on {v['platform']}",
        "packages   " + ", ".join(f"{k} {x or 'MISSING'}" for k, x in v["packages"].items()),
        f"C core     {'loaded from ' + core['path'] if core['loaded'] else core['error']}",
        "extras     " + (", ".join(extras) or "unknown (robocli-robots is not installed)"),
    ]
    if serial["error"]:
        out.append(f"serial     cannot list ports: {serial['error']}")
    elif not serial["ports"]:
        out.append("serial     no ports found (is the USB-serial adapter plugged in?)")
    for p in serial["ports"]:
        access = "you may open it" if p["may_open"] else "you may NOT open it"
        out.append(f"serial     {p['device']}  {p['description']}  ({access})")
    group = serial.get("group")
    if group and group["exists"]:
        state = "member" if group["active"] else "member after a new login" if group[
            "member"] else "not a member"  # fmt: skip
        out.append(f"group      {group['name']}: {state}"
                   + (f"; {group['advice']}" if group["advice"] else ""))  # fmt: skip
    for name, a in r["addresses"].items():
        source = {"env": f"${a['env']}", "given": "given"}.get(a["source"], "default")
        answer = {True: "answers", False: "no answer", None: "not probed"}[a["answers"]]
        out.append(f"{name:<11}{a['address']} ({source}): {answer}: {a['detail']}")
    return out + [f"PROBLEM    {problem}" for problem in r["problems"]]
