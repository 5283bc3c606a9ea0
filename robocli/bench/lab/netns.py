"""A lab of robots, laptops and a lab server on one machine, in Linux network namespaces.

:class:`Lab` builds, as root, one namespace per robot (``<prefix>-r0``...), per laptop
(``<prefix>-l0``...) and for the lab server (``<prefix>-srv``); each has a veth pair whose
other end sits on a Linux bridge in a namespace of its own (``<prefix>-br``), so nothing is
added to the machine's own network. Addresses are assigned in ``10.77.0.0/16``: the server
``10.77.0.1``, robot *i* ``10.77.1.(i+1)``, laptop *j* ``10.77.(2 + j // 250).(j % 250 + 1)``.
Each robot's uplink (its ``eth0``, robot to bridge) is shaped with a token bucket
(``tc qdisc ... tbf``) to a Wi-Fi-like rate.

Processes run inside a namespace with ``ip netns exec`` (:meth:`Lab.spawn`), each in its own
session, its output in a log file. On every ending of the ``with`` block (an error, Ctrl-C, a
failed test) every process is killed (SIGTERM, then SIGKILL) and every namespace deleted
(deleting a namespace deletes its veth ends and the bridge). The prefix holds this process's
id (``rcl-<pid>``), so that two labs never clash, and :func:`remove_stale` deletes the
namespaces of a lab whose process died without cleaning up (SIGKILL).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import subprocess
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from robocli.errors import RobocliError

PREFIX_ROOT = "rcl"
NETNS_DIR = Path("/var/run/netns")
COMMAND_TIMEOUT_S = 10.0
STOP_GRACE_S = 2.0


class LabError(RobocliError):
    """The lab could not be built (not root, no ``ip``, a namespace refused)."""


def unavailable_reason() -> str | None:
    """Why this machine cannot build a lab (one line), or None when it can: root, ``ip`` and
    ``tc`` from iproute2, and a namespace that can actually be made."""
    if not hasattr(os, "geteuid") or os.geteuid() != 0:
        return "the lab needs root (ip netns add)"
    for tool in ("ip", "tc"):
        if shutil.which(tool) is None:
            return f"the lab needs '{tool}' from iproute2 (apt-get install iproute2)"
    probe = f"{PREFIX_ROOT}-{os.getpid()}-probe"
    made = subprocess.run(["ip", "netns", "add", probe], capture_output=True, text=True,
                          timeout=COMMAND_TIMEOUT_S)  # fmt: skip
    if made.returncode != 0:
        return f"cannot make a network namespace: {made.stderr.strip() or made.returncode}"
    subprocess.run(["ip", "netns", "del", probe], capture_output=True, timeout=COMMAND_TIMEOUT_S)
    return None


def run(*argv: str, ns: str | None = None, check: bool = True) -> str:
    """Run ``argv`` (in namespace ``ns``), return its stdout; a failure raises LabError."""
    cmd = ["ip", "netns", "exec", ns, *argv] if ns else list(argv)
    try:
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=COMMAND_TIMEOUT_S)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise LabError(f"{' '.join(cmd)}: {exc}") from None
    if check and done.returncode != 0:
        raise LabError(f"{' '.join(cmd)}: {done.stderr.strip() or 'exit ' + str(done.returncode)}")
    return done.stdout


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_stale() -> list[str]:
    """Delete the namespaces of labs whose process is gone (``rcl-<pid>-...`` with no such
    pid). Returns their names."""
    gone = []
    for line in run("ip", "netns", "list", check=False).splitlines():
        name = line.split()[0] if line.split() else ""
        m = re.fullmatch(rf"{PREFIX_ROOT}-(\d+)-[\w-]+", name)
        if m and not _pid_alive(int(m[1])):
            run("ip", "netns", "del", name, check=False)
            gone.append(name)
    return gone


@dataclass
class Node:
    """One namespace of the lab: its name, role, index and address."""

    ns: str
    role: str  # "robot", "laptop", "server"
    index: int
    address: str
    port: str  # its veth end on the bridge


@dataclass
class Proc:
    """A process started in a namespace (:meth:`Lab.spawn`)."""

    node: Node
    name: str
    popen: subprocess.Popen[str]
    log: Path

    @property
    def pid(self) -> int:
        return self.popen.pid

    def tail(self, lines: int = 20) -> str:
        """The last lines of its log (stdout and stderr)."""
        try:
            text = self.log.read_text(errors="replace")
        except OSError:
            return ""
        return "\n".join(text.splitlines()[-lines:])

    def json_lines(self, lines: int) -> list[dict[str, Any]]:
        """The JSON objects among the last ``lines`` lines of its log (others are passed
        over: a line cut short, a warning)."""
        out = []
        for line in self.tail(lines).splitlines():
            if line.startswith("{"):
                try:
                    out.append(json.loads(line))
                except ValueError:
                    continue
        return out


@dataclass
class Lab:
    """``robots`` robot, ``laptops`` laptop namespaces and a server one on a bridge, robot
    uplinks shaped to ``uplink_mbit`` Mbit/s (None: not shaped). Use as a context manager."""

    robots: int
    laptops: int
    uplink_mbit: float | None = 20.0
    tbf_latency_ms: float = 100.0  #: how long a packet may wait in the robot's queue
    prefix: str = field(default_factory=lambda: f"{PREFIX_ROOT}-{os.getpid()}")
    nodes: list[Node] = field(default_factory=list)
    procs: list[Proc] = field(default_factory=list)
    logdir: Path | None = None
    _made: list[str] = field(default_factory=list)

    # ---------------------------------------------------------------- building

    @property
    def bridge_ns(self) -> str:
        return f"{self.prefix}-br"

    @property
    def server(self) -> Node:
        return next(n for n in self.nodes if n.role == "server")

    def robot(self, i: int) -> Node:
        return next(n for n in self.nodes if n.role == "robot" and n.index == i)

    def laptop(self, j: int) -> Node:
        return next(n for n in self.nodes if n.role == "laptop" and n.index == j)

    def __enter__(self) -> Lab:
        if self.robots < 1 or self.laptops < 1 or self.laptops > 250 * 250:
            raise LabError(f"a lab of {self.robots} robots x {self.laptops} laptops")
        self.logdir = Path(tempfile.mkdtemp(prefix=f"{self.prefix}-"))
        try:
            self._build()
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _add_ns(self, name: str) -> None:
        run("ip", "netns", "add", name)
        self._made.append(name)
        run("ip", "-n", name, "link", "set", "lo", "up")

    def _build(self) -> None:
        remove_stale()
        self._add_ns(self.bridge_ns)
        run("ip", "-n", self.bridge_ns, "link", "add", "br0", "type", "bridge")
        run("ip", "-n", self.bridge_ns, "link", "set", "br0", "up")
        self.nodes = [Node(f"{self.prefix}-srv", "server", 0, "10.77.0.1", "srv")]
        for i in range(self.robots):
            self.nodes.append(Node(f"{self.prefix}-r{i}", "robot", i, f"10.77.1.{i + 1}", f"r{i}"))
        for j in range(self.laptops):
            addr = f"10.77.{2 + j // 250}.{j % 250 + 1}"
            self.nodes.append(Node(f"{self.prefix}-l{j}", "laptop", j, addr, f"l{j}"))
        for node in self.nodes:
            self._add_ns(node.ns)
            run("ip", "link", "add", "eth0", "netns", node.ns, "type", "veth",
                "peer", "name", node.port, "netns", self.bridge_ns)  # fmt: skip
            run("ip", "-n", self.bridge_ns, "link", "set", node.port, "master", "br0", "up")
            run("ip", "-n", node.ns, "addr", "add", f"{node.address}/16", "dev", "eth0")
            run("ip", "-n", node.ns, "link", "set", "eth0", "up")
            if node.role == "robot" and self.uplink_mbit:
                self.shape(node, self.uplink_mbit)

    def shape(self, node: Node, mbit: float) -> None:
        """Shape ``node``'s uplink (its ``eth0`` egress) to ``mbit`` Mbit/s with a token
        bucket; its queue holds :attr:`tbf_latency_ms` of traffic."""
        burst = max(32 * 1024, int(mbit * 1e6 / 8 / 250))  # at least one HZ=250 tick's worth
        run("tc", "-n", node.ns, "qdisc", "replace", "dev", "eth0", "root", "tbf",
            "rate", f"{mbit:g}mbit", "burst", str(burst),
            "latency", f"{self.tbf_latency_ms:g}ms")  # fmt: skip

    # ---------------------------------------------------------------- processes

    def spawn(self, node: Node, argv: Sequence[str], name: str, *, stdin: bool = False) -> Proc:
        """Start ``argv`` in ``node``'s namespace, in its own session (a Ctrl-C reaches
        only us), its stdout and stderr in a log file; ``stdin``: a pipe to it."""
        assert self.logdir is not None
        log = self.logdir / f"{name}.log"
        with log.open("w") as out:
            popen = subprocess.Popen(
                ["ip", "netns", "exec", node.ns, *argv], stdout=out, stderr=subprocess.STDOUT,
                stdin=subprocess.PIPE if stdin else subprocess.DEVNULL, text=True,
                start_new_session=True, env={**os.environ, "PYTHONUNBUFFERED": "1"},
            )  # fmt: skip
        proc = Proc(node, name, popen, log)
        self.procs.append(proc)
        return proc

    def stop(self, proc: Proc, sig_first: bool = True) -> None:
        """Stop ``proc`` and its process group: its stdin closed, SIGTERM, then SIGKILL."""
        p = proc.popen
        with contextlib.suppress(OSError):
            if p.stdin is not None:
                p.stdin.close()
        for sig in (15, 9) if sig_first else (9,):
            if p.poll() is not None:
                break
            with contextlib.suppress(OSError):
                os.killpg(p.pid, sig)
            with contextlib.suppress(subprocess.TimeoutExpired):
                p.wait(STOP_GRACE_S)
        with contextlib.suppress(OSError):
            os.killpg(p.pid, 9)  # what it left behind in its group
        with contextlib.suppress(subprocess.TimeoutExpired):
            p.wait(STOP_GRACE_S)

    def close(self) -> None:
        """Kill every process, delete every namespace made (whatever failed before)."""
        for proc in reversed(self.procs):
            with contextlib.suppress(Exception):
                self.stop(proc)
        for proc in self.procs:  # the ones started in a namespace's own pid space die with it
            with contextlib.suppress(Exception):
                for pid in _pids_in(proc.node.ns):
                    os.kill(pid, 9)
        for ns in reversed(self._made):
            run("ip", "netns", "del", ns, check=False)
        self._made.clear()

    # ---------------------------------------------------------------- counters

    def tx_bytes(self, node: Node, dev: str = "eth0") -> int:
        """Bytes sent so far on ``node``'s ``dev`` (its uplink for a robot)."""
        out = run("ip", "-n", node.ns, "-s", "-j", "link", "show", "dev", dev)
        try:
            return int(json.loads(out)[0]["stats64"]["tx"]["bytes"])
        except (ValueError, KeyError, IndexError, TypeError) as exc:
            raise LabError(f"no counters for {dev} in {node.ns}: {exc}") from None

    def qdisc_drops(self, node: Node, dev: str = "eth0") -> int:
        """Packets the robot's token bucket dropped so far (its queue full)."""
        out = run("tc", "-n", node.ns, "-s", "-j", "qdisc", "show", "dev", dev)
        try:
            return int(sum(q.get("drops", 0) for q in json.loads(out)))
        except (ValueError, TypeError) as exc:
            raise LabError(f"no qdisc counters for {dev} in {node.ns}: {exc}") from None


def _pids_in(ns: str) -> list[int]:
    out = run("ip", "netns", "pids", ns, check=False)
    return [int(t) for t in out.split() if t.isdigit()]


def wait_for(predicate: object, timeout: float, what: str, procs: Sequence[Proc] = ()) -> None:
    """Poll ``predicate()`` until true within ``timeout`` s; LabError saying ``what`` (and
    the tail of a process of ``procs`` that ended) when it does not come."""
    assert callable(predicate)
    deadline = time.monotonic() + timeout
    while True:
        if predicate():
            return
        for proc in procs:
            if proc.popen.poll() is not None:
                raise LabError(f"{proc.name} ended (exit {proc.popen.returncode}) while "
                               f"waiting for {what}:\n{proc.tail()}")  # fmt: skip
        if time.monotonic() > deadline:
            raise LabError(f"no {what} within {timeout:g} s")
        time.sleep(0.05)
