"""``serve --zenoh``, ``subscribe --zenoh``, ``list``, ``router`` as real processes on
loopback (explicit endpoints, multicast scouting off), and the one line without the extra."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from tests.peers import free_endpoint
from tests.waiting import wait_for

DEADLINE_S = 30.0
ENV = {**os.environ, "PYTHONUNBUFFERED": "1"}


def robocli(*args: str, timeout: float = 60.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "robocli", *args], capture_output=True,
                          text=True, timeout=timeout, env=ENV)  # fmt: skip


@contextmanager
def running(*args: str, ready: str, cwd: Path | None = None) -> Iterator[subprocess.Popen[str]]:
    """A robocli process (in ``cwd``), once it printed a line containing ``ready``; killed
    at the end."""
    proc = subprocess.Popen([sys.executable, "-m", "robocli", *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=ENV, cwd=cwd)  # fmt: skip
    try:
        _until(proc, ready)
        yield proc
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(DEADLINE_S)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(DEADLINE_S)


def _until(proc: subprocess.Popen[str], needle: str) -> None:
    """Read ``proc``'s output until a line contains ``needle`` (a thread reads; the deadline
    bounds a failure). The rest of its output is read and dropped, never blocking it."""
    found = threading.Event()
    seen: list[str] = []

    def read() -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            seen.append(line)
            if needle in line:
                found.set()

    threading.Thread(target=read, daemon=True).start()
    if not found.wait(DEADLINE_S):
        err = proc.stderr.read() if proc.poll() is not None and proc.stderr else ""
        raise AssertionError(f"{needle!r} not in {seen} {err}")


def hubs_listed(endpoint: str) -> list[str]:
    out = robocli("list", "--zenoh", endpoint, "--json", "--timeout", "1")
    assert out.returncode == 0, out.stderr
    return [f"{x['kind']} {x['name']}" for x in json.loads(out.stdout)]


def test_subscribe_prints_the_rows_of_a_hub_serving_on_zenoh() -> None:
    ep = free_endpoint()
    with running("serve", "--sim", "--port", "0", "--zenoh", ep, "--name", "lab1",
                 ready="hub serving"):  # fmt: skip
        out = robocli("subscribe", "adc", "--rate", "100", "--zenoh", ep, "--count", "20",
                      "-f", "csv")  # fmt: skip
        assert out.returncode == 0, out.stderr
        lines = out.stdout.splitlines()
        assert lines[0] == "t," + ",".join(f"ch{i}" for i in range(8))
        rows = [[float(x) for x in line.split(",")] for line in lines[1:]]
        assert len(rows) == 20 and all(len(r) == 9 for r in rows)
        t = [r[0] for r in rows]
        assert all(b > a for a, b in zip(t, t[1:], strict=False))
        assert abs(t[-1] - time.time()) < 10.0
        assert "lost" not in out.stderr, out.stderr
        named = robocli("subscribe", "imu", "--rate", "200", "--zenoh", ep, "--hub", "lab1",
                        "--count", "5", "--json")  # fmt: skip
        assert named.returncode == 0, named.stderr
        assert len(named.stdout.splitlines()) == 5 and '"ax"' in named.stdout
        nobody = robocli("subscribe", "adc", "--rate", "10", "--zenoh", ep, "--hub", "other",
                         "--count", "1")  # fmt: skip
        assert nobody.returncode == 3, nobody.stderr
        assert nobody.stderr.strip().count("\n") == 0 and "'other'" in nobody.stderr


def test_list_shows_the_hub_through_a_router_and_loses_it_when_it_dies(tmp_path: Path) -> None:
    router_ep, hub_ep = free_endpoint(), free_endpoint()
    config = tmp_path / "robot.json5"  # the lab set-up: a robot's hub connects to the router
    config.write_text(json.dumps({
        "mode": "peer", "connect": {"endpoints": [router_ep]}, "listen": {"endpoints": [hub_ep]},
        "scouting": {"multicast": {"enabled": False}},
    }))  # fmt: skip
    with running("router", "--listen", router_ep, ready="zenoh router"):
        assert hubs_listed(router_ep) == []
        with running("serve", "--sim", "--no-tcp", "--zenoh", str(config), "--name", "robot1",
                     ready="hub serving") as hub:  # fmt: skip
            wait_for(lambda: hubs_listed(router_ep) == ["hub robot1"], "the hub listed")
            out = robocli("subscribe", "adc", "--rate", "100", "--zenoh", router_ep,
                          "--count", "3")  # fmt: skip
            assert out.returncode == 0 and len(out.stdout.splitlines()) == 4, out.stderr
            hub.kill()  # no goodbye: its liveliness goes with its connection
            hub.wait(DEADLINE_S)
            wait_for(lambda: hubs_listed(router_ep) == [], "the hub gone from the list")


def test_router_refuses_a_wrong_password(tmp_path: Path) -> None:
    ep = free_endpoint()
    users = tmp_path / "users.txt"
    users.write_text("alice:correct horse\n")

    def client(password: str | None) -> Path:
        cfg: dict[str, object] = {"mode": "client", "connect": {"endpoints": [ep]},
                                  "scouting": {"multicast": {"enabled": False}}}  # fmt: skip
        if password is not None:
            cfg["transport"] = {"auth": {"usrpwd": {"user": "alice", "password": password}}}
        path = tmp_path / f"client-{password}.json5"
        path.write_text(json.dumps(cfg))
        return path

    with running("router", "--listen", ep, "--users", str(users), ready="zenoh router"):
        ok = robocli("list", "--zenoh", str(client("correct horse")), "--json")
        assert ok.returncode == 0 and json.loads(ok.stdout) == [], ok.stderr
        for wrong in ("wrong", None):
            refused = robocli("list", "--zenoh", str(client(wrong)))
            assert refused.returncode == 3, refused.stderr
            line = refused.stderr.strip()
            assert "\n" not in line and line.startswith("robocli: zenoh: cannot connect to")


def test_bad_users_file_is_a_usage_error(tmp_path: Path) -> None:
    users = tmp_path / "users.txt"
    users.write_text("no colon here\n")
    out = robocli("router", "--listen", free_endpoint(), "--users", str(users))
    assert out.returncode == 2 and "line 1 is not user:password" in out.stderr


BLOCKED = (
    "import sys; sys.modules['zenoh'] = None; from robocli.cli import main; "
    "sys.exit(main(sys.argv[1:]))"
)


def test_without_the_extra_each_command_says_how_to_install() -> None:
    for args in (
        ["subscribe", "adc", "--rate", "10", "--zenoh"],
        ["serve", "--sim", "--port", "0", "--zenoh", "tcp/127.0.0.1:1"],
        ["list"],
        ["router"],
    ):
        out = subprocess.run([sys.executable, "-c", BLOCKED, *args], capture_output=True,
                             text=True, timeout=60, env=ENV)  # fmt: skip
        assert out.returncode == 1, (args, out.stderr)
        assert out.stderr == (
            "robocli: Zenoh support needs Eclipse Zenoh: pip install 'robocli-robots[zenoh]'\n"
        ), args


def test_subscribe_needs_the_token_to_change_a_hubs_settings(tmp_path: Path) -> None:
    ep = free_endpoint()
    token = tmp_path / "token"
    token.write_text("s3cret\n")
    with running("serve", "--sim", "--no-tcp", "--zenoh", ep, "--token-file", str(token),
                 ready="hub serving"):  # fmt: skip
        refused = robocli("subscribe", "imu", "--rate", "200", "--zenoh", ep, "--count", "1")
        assert refused.returncode == 4, refused.stderr
        assert refused.stderr.count("\n") == 1 and "unauthorized" in refused.stderr
        ok = robocli("subscribe", "imu", "--rate", "200", "--zenoh", ep, "--count", "3",
                     "--token-file", str(token))  # fmt: skip
        assert ok.returncode == 0 and len(ok.stdout.splitlines()) == 4, ok.stderr
