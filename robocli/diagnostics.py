"""What ``robocli doctor`` reports, as one JSON-ready dict: versions, whether the C core
loaded, the serial ports and whether this user may open them (the dialout group), which
optional extras are installed, and whether the default addresses answer.

The addresses are those of :mod:`robocli.defaults` (``ROBOCLI_PIONEER``, ``ROBOCLI_ARM``,
``ROBOCLI_HUB``, else this machine's simulators' ports). Each probe is short and leaves the
device as it found it: a Pioneer over TCP is sent SYNC0 (the first handshake packet, which
an ARCOS robot echoes) and left; an arm's motion port is only connected to (an ABB restarts
its motion task on anything but a trajectory point), its state port read until a message
arrives; a hub is sent ros4mat CONNECT, then QUIT. A serial port is never opened (opening
one can reset the board behind it): it is checked for existence and permission. Probes run
at once, each socket operation bounded by ``timeout``, the whole by a deadline, so that a
name that never resolves cannot hang the report.
"""

from __future__ import annotations

import importlib.metadata
import os
import platform
import re
import socket
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

from robocli import defaults
from robocli._version import DIST_NAME, __version__
from robocli.errors import RobocliError

__all__ = ["PROBE_TIMEOUT", "diagnose", "probe_addresses"]

#: Seconds each socket operation of a probe may take.
PROBE_TIMEOUT = 1.0
#: The distribution's own requirements when its metadata is missing (run from a checkout).
_CORE = ("cffi", "numpy", "typer", "rich", "pyserial", "construct")
_REQUIREMENT = re.compile(r"^\s*([A-Za-z0-9][A-Za-z0-9._\-]*)")
_EXTRA = re.compile(r"""extra\s*==\s*["']([^"']+)["']""")


def diagnose(
    *,
    pioneer: str | None = None,
    arm: str | None = None,
    hub: str | None = None,
    motion_port: int = defaults.ARM_MOTION_PORT,
    state_port: int = defaults.ARM_STATE_PORT,
    timeout: float = PROBE_TIMEOUT,
) -> dict[str, Any]:
    """The whole report. ``pioneer``/``arm``/``hub``: addresses to probe instead of the
    defaults (None: the variable, else the default). ``t`` is Unix epoch seconds; every
    probe's ``ms`` is its own duration."""
    requirements = _requirements()
    report = {
        "t": time.time(),
        "versions": _versions(requirements),
        "c_core": _c_core(),
        "extras": _extras(requirements),
        "serial": _serial(),
        "addresses": probe_addresses(
            pioneer=pioneer,
            arm=arm,
            hub=hub,
            motion_port=motion_port,
            state_port=state_port,
            timeout=timeout,
        ),
    }
    report["problems"] = _problems(report)
    return report


def _problems(report: dict[str, Any]) -> list[str]:
    """What stops robocli from working here (not: a device that is simply away)."""
    problems = []
    core = report["c_core"]
    if not core["loaded"]:
        problems.append(f"the C core did not load ({core['error']}): reinstall robocli "
                        "with a C compiler and the Python headers")  # fmt: skip
    serial = report["serial"]
    closed = [p["device"] for p in serial["ports"] if not p["may_open"]]
    if closed:
        advice = (serial.get("group") or {}).get("advice")
        problems.append(f"you may not open {', '.join(closed)}" + (f": {advice}" if advice else ""))
    return problems


# ------------------------------------------------------------------------- packages


def _requirements() -> list[tuple[str, str]] | None:
    """``(distribution, extra or "")`` of robocli's installed metadata; None without it."""
    try:
        lines = importlib.metadata.metadata(DIST_NAME).get_all("Requires-Dist") or []
    except importlib.metadata.PackageNotFoundError:
        return None
    out = []
    for line in lines:
        name = _REQUIREMENT.match(line)
        extra = _EXTRA.search(line)
        if name:
            out.append((name[1], extra[1] if extra else ""))
    return out


def _version_of(dist: str) -> str | None:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return None


def _versions(requirements: list[tuple[str, str]] | None) -> dict[str, Any]:
    core = [d for d, extra in requirements if not extra] if requirements else list(_CORE)
    return {
        "robocli": __version__,
        "python": platform.python_version(),
        "implementation": platform.python_implementation(),
        "platform": platform.platform(),
        "packages": {dist: _version_of(dist) for dist in core},
    }


def _extras(requirements: list[tuple[str, str]] | None) -> dict[str, Any]:
    """``{extra: {"installed": all present, "packages": {dist: version or None}}}``."""
    if requirements is None:
        return {}
    extras: dict[str, dict[str, str | None]] = {}
    for dist, extra in requirements:
        if extra:
            extras.setdefault(extra, {})[dist] = _version_of(dist)
    return {
        name: {"installed": all(v is not None for v in dists.values()), "packages": dists}
        for name, dists in extras.items()
    }


def _c_core() -> dict[str, Any]:
    try:
        from robocli import _core
        from robocli.core import arcos_checksum
    except (ImportError, OSError) as exc:
        return {"loaded": False, "path": None, "error": f"{type(exc).__name__}: {exc}"}
    try:  # one known answer: the checksum of a CONFIG reply's first bytes (0x20 0x01 0x02)
        working = arcos_checksum(b"\x20\x01\x02") == 0x2003
    except Exception as exc:
        return {"loaded": True, "path": _core.__file__, "error": f"{type(exc).__name__}: {exc}"}
    return {"loaded": working, "path": _core.__file__,
            "error": None if working else "wrong checksum: the build is broken"}  # fmt: skip


# --------------------------------------------------------------------------- serial


def _serial() -> dict[str, Any]:
    """The serial ports, whether this user may open each, and the group that grants it."""
    try:
        from serial.tools import list_ports

        found = sorted(list_ports.comports(), key=lambda p: p.device)
    except Exception as exc:
        return {"ports": [], "error": f"{type(exc).__name__}: {exc}", "group": None}
    ports = [
        {"device": p.device, "description": p.description, "hwid": p.hwid,
         **_access(p.device)}
        for p in found
    ]  # fmt: skip
    named = {p["group"] for p in ports if p.get("group")}
    group = named.pop() if len(named) == 1 else None
    return {"ports": ports, "error": None, "group": _group(group)}


def _access(device: str) -> dict[str, Any]:
    """Whether ``device`` may be opened for reading and writing, and its owning group."""
    out: dict[str, Any] = {"may_open": os.access(device, os.R_OK | os.W_OK), "group": None}
    if os.name == "posix":
        import grp

        try:
            out["group"] = grp.getgrgid(os.stat(device).st_gid).gr_name
        except (OSError, KeyError):
            pass
    return out


def _group(name: str | None) -> dict[str, Any] | None:
    """The group that grants serial ports (the ports' own, else ``dialout``, else ``uucp``
    as on Arch): whether this user is in it, and whether this session has it yet."""
    if os.name != "posix":
        return None  # Windows: COM ports need no group
    import getpass
    import grp

    try:
        user = getpass.getuser()
    except (KeyError, OSError):
        user = ""
    entry = None
    for candidate in (name, "dialout", "uucp"):
        if candidate:
            try:
                entry = grp.getgrnam(candidate)
                break
            except KeyError:
                continue
    if entry is None:
        return {"name": name or "dialout", "exists": False, "member": False, "active": False,
                "advice": None}  # fmt: skip
    primary = os.getgid() == entry.gr_gid
    member = primary or user in entry.gr_mem or os.geteuid() == 0
    active = primary or entry.gr_gid in os.getgroups() or os.geteuid() == 0
    advice = None
    if not member:
        advice = (f"sudo usermod -aG {entry.gr_name} {user or '$USER'}, "
                  "then log out and in again")  # fmt: skip
    elif not active:
        advice = f"log out and in again: this session started before you joined {entry.gr_name}"
    return {"name": entry.gr_name, "exists": True, "member": member, "active": active,
            "advice": advice}  # fmt: skip


# ------------------------------------------------------------------------ addresses


def probe_addresses(
    *,
    pioneer: str | None = None,
    arm: str | None = None,
    hub: str | None = None,
    motion_port: int = defaults.ARM_MOTION_PORT,
    state_port: int = defaults.ARM_STATE_PORT,
    timeout: float = PROBE_TIMEOUT,
) -> dict[str, dict[str, Any]]:
    """Probe the Pioneer, the arm's two ports and the hub at once; see the module text.
    Each entry: ``address``, ``env`` (its variable), ``source`` (``given``, ``env`` or
    ``default``), ``answers`` (True, False, or None where nothing is probed: a serial port,
    ``sim``), ``detail``, ``ms``."""
    chosen = {}
    for device, given in (("pioneer", pioneer), ("arm", arm), ("hub", hub)):
        if given:
            chosen[device] = (given.strip(), "given")
        else:
            address, from_env = defaults.address(device)
            chosen[device] = (address, "env" if from_env else "default")
    envs = {"pioneer": defaults.PIONEER_ENV, "arm": defaults.ARM_ENV, "hub": defaults.HUB_ENV}
    jobs: dict[str, tuple[str, Callable[[], tuple[bool | None, str]]]] = {
        "pioneer": (chosen["pioneer"][0], lambda: _probe_pioneer(chosen["pioneer"][0], timeout)),
        "arm_motion": _arm_job(chosen["arm"][0], motion_port, "motion", timeout),
        "arm_state": _arm_job(chosen["arm"][0], state_port, "state", timeout),
        "hub": (chosen["hub"][0], lambda: _probe_hub(chosen["hub"][0], timeout)),
    }
    results: dict[str, dict[str, Any]] = {}
    threads = []
    for name, (address, job) in jobs.items():
        device = name.split("_", 1)[0]
        entry = {"address": address, "env": envs[device], "source": chosen[device][1],
                 "answers": False, "detail": "", "ms": None}  # fmt: skip
        results[name] = entry
        thread = threading.Thread(target=_run, args=(job, entry), daemon=True,
                                  name=f"doctor-{name}")  # fmt: skip
        thread.start()
        threads.append((thread, entry))
    deadline = time.monotonic() + 3 * timeout + 1.0  # connect + exchange, with room
    for thread, entry in threads:
        thread.join(max(0.0, deadline - time.monotonic()))
        if thread.is_alive():  # e.g. a name resolver that does not answer: left behind
            entry.update(answers=False, detail=f"no answer within {3 * timeout + 1.0:g} s")
    return results


def _run(job: Callable[[], tuple[bool | None, str]], entry: dict[str, Any]) -> None:
    start = time.perf_counter()
    try:
        answers, detail = job()
    except RobocliError as exc:
        answers, detail = False, str(exc)
    except OSError as exc:
        answers, detail = False, _why(exc)
    except Exception as exc:
        answers, detail = False, f"{type(exc).__name__}: {exc}"
    entry.update(answers=answers, detail=detail,
                 ms=round((time.perf_counter() - start) * 1e3, 3))  # fmt: skip


def _why(exc: OSError) -> str:
    if isinstance(exc, ConnectionRefusedError):
        return "connection refused (nothing listens there)"
    if isinstance(exc, TimeoutError):
        return "no answer (timed out)"
    if isinstance(exc, socket.gaierror):
        return f"name not resolved: {exc.strerror or exc}"
    return exc.strerror or str(exc)


def _connect(host: str, port: int, timeout: float) -> socket.socket:
    return socket.create_connection((host, port), timeout=timeout)


def _read_some(sock: socket.socket, n: int, timeout: float) -> bytes:
    """Up to ``n`` bytes, waiting at most ``timeout`` s in all; b"" if the peer closed."""
    deadline = time.monotonic() + timeout
    data = b""
    while len(data) < n:
        left = deadline - time.monotonic()
        if left <= 0:
            break
        sock.settimeout(left)
        try:
            chunk = sock.recv(n - len(data))
        except TimeoutError:
            break
        if not chunk:
            break
        data += chunk
    return data


def _probe_pioneer(url: str, timeout: float) -> tuple[bool | None, str]:
    from robocli.protocols.arcos import wire
    from robocli.transports import check_url, is_tcp, parse_address

    if url.lower() == "sim":
        return None, "the embedded simulator (started by each command): nothing to probe"
    text = check_url(url, what="pioneer")
    scheme = text.split("://", 1)[0] if "://" in text else ""
    if is_tcp(text):
        host, port = parse_address(text)
        with _connect(host, port, timeout) as sock:
            sock.sendall(wire.frame(bytes((wire.PacketType.SYNC0,))))
            reply = _read_some(sock, 6, timeout)
        if reply[:2] == wire.SYNC:
            return True, "an ARCOS robot: it answered SYNC0"
        if reply:
            return False, f"something answered, not in ARCOS: {reply[:16]!r}"
        return False, f"connected, but no ARCOS reply within {timeout:g} s"
    if scheme:
        return None, f"a pyserial URL ({scheme}://): not probed"
    return None, _serial_path(text)


def _serial_path(path: str) -> str:
    if not os.path.exists(path):
        return "no such serial port (is the USB-serial adapter plugged in?)"
    if os.access(path, os.R_OK | os.W_OK):
        return "a serial port you may open (not opened: that can reset the board)"
    return "a serial port you may not open: see serial.group.advice"


def _arm_job(host: str, port: int, which: str,
             timeout: float) -> tuple[str, Callable[[], tuple[bool | None, str]]]:  # fmt: skip
    """(the address shown, the probe) of one arm port."""
    from robocli.transports import InvalidURL, format_address, parse_host

    try:
        shown = format_address(parse_host(host), port)
    except InvalidURL:
        shown = host  # `sim`, or malformed: the probe says which
    return shown, lambda: _probe_arm(host, port, which, timeout)


def _probe_arm(host: str, port: int, which: str, timeout: float) -> tuple[bool | None, str]:
    from robocli.transports import parse_host

    if host.lower() == "sim":
        return None, "the embedded simulator (started by each command): nothing to probe"
    with _connect(parse_host(host, what="arm"), port, timeout) as sock:
        if which == "motion":  # never send: an ABB motion server restarts on anything else
            if _closed_at_once(sock, min(timeout, 0.2)):
                return False, "connected, then closed by the controller (another client?)"
            return True, "the motion port accepts a connection (nothing sent)"
        first = _read_some(sock, 4, timeout)
    if len(first) == 4:
        return True, "the state port streams Simple Message"
    if first == b"" and timeout > 0:
        return False, f"connected, but no state message within {timeout:g} s"
    return False, f"connected, then only {len(first)} bytes"


def _closed_at_once(sock: socket.socket, wait: float) -> bool:
    """Whether the peer closes ``sock`` within ``wait`` s (as a server that already has
    its one client does); reads nothing."""
    sock.settimeout(wait)
    try:
        return sock.recv(1, socket.MSG_PEEK) == b""
    except TimeoutError:
        return False
    except OSError:
        return True


def _probe_hub(address: str, timeout: float) -> tuple[bool | None, str]:
    from robocli.devices.hub.client import Hub, parse_hub

    host, port = parse_hub(address)
    with Hub.connect(host, port, timeout=timeout) as hub:
        client = hub.client_id
    return True, f"a ros4mat hub: CONNECT answered (client id {client})"


if __name__ == "__main__":  # pragma: no cover - `python -m robocli.diagnostics`: the raw dict
    import json

    json.dump(diagnose(), sys.stdout, indent=2, default=str)
