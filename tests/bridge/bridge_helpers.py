"""What the bridge tests share: a bridge process over a simulator, a raw Zenoh controller,
waits on events with deadlines that only bound a failure."""

from __future__ import annotations

import contextlib
import json
import os
import queue
import subprocess
import sys
import threading
from collections.abc import Iterator
from typing import Any, TypeVar

T = TypeVar("T")
DEADLINE = 20.0  #: seconds that only bound a failure


@contextlib.contextmanager
def bridge_process(args: list[str]) -> Iterator[tuple[subprocess.Popen[str], str]]:
    """``robocli bridge ARGS`` in its own process; yield it and its first line (ready)."""
    with robocli_process(["bridge", *args], "bridge ") as started:
        yield started


@contextlib.contextmanager
def robocli_process(args: list[str], ready: str) -> Iterator[tuple[subprocess.Popen[str], str]]:
    """``robocli ARGS`` in its own process until its first line starts with ``ready``; yield
    it and that line; terminated (then killed) at the end."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "robocli", *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )  # fmt: skip
    try:
        line = read_line(proc, DEADLINE)
        if not line.startswith(ready):
            proc.kill()
            raise AssertionError(f"robocli {args[0]} did not start: {line!r} "
                                 f"{proc.stderr.read()!r}")  # fmt: skip
        yield proc, line
    finally:
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(DEADLINE)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        for pipe in (proc.stdout, proc.stderr):
            if pipe is not None:
                pipe.close()


def read_line(proc: subprocess.Popen[str], timeout: float) -> str:
    """The process's next stdout line, or "" after ``timeout`` s or at its end."""
    out: queue.Queue[str] = queue.Queue()
    assert proc.stdout is not None
    stdout = proc.stdout
    threading.Thread(target=lambda: out.put(stdout.readline()), daemon=True).start()
    try:
        return out.get(timeout=timeout)
    except queue.Empty:
        return ""


class Events:
    """Every JSON put on ``key`` (a subscriber on ``session``), kept in order."""

    def __init__(self, session: Any, key: str) -> None:
        self.items: list[dict[str, Any]] = []
        self._sub = session.declare_subscriber(
            key, lambda s: self.items.append(json.loads(s.payload.to_bytes()))
        )

    def find(self, **fields: Any) -> dict[str, Any] | None:
        for item in list(self.items):
            if all(item.get(k) == v for k, v in fields.items()):
                return item
        return None


def acquire(session: Any, robot: str, holder: str) -> dict[str, Any]:
    """The reply to ``{"op": "acquire"}`` on ``holder``'s request key of ``robot``."""
    return query(session, f"robocli/{robot}/@control/{holder}/request", {"op": "acquire"})


def holder_token(session: Any, robot: str, holder: str) -> Any:
    """``holder``'s liveliness token on ``robot`` (what a granted controller declares)."""
    return session.liveliness().declare_token(f"robocli/{robot}/@control/{holder}/alive")


def query(session: Any, key: str, payload: dict[str, Any] | None = None) -> dict[str, Any]:
    """The first reply to a query on ``key`` (JSON), ok or error."""
    body = None if payload is None else json.dumps(payload).encode()
    for reply in session.get(key, payload=body, timeout=DEADLINE):
        sample = reply.ok if reply.ok is not None else reply.err
        result: dict[str, Any] = json.loads(sample.payload.to_bytes())
        return result
    raise AssertionError(f"no reply on {key}")
