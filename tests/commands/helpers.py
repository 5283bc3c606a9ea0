"""Run ``robocli`` as a user does: a real process, its exit code and its one stderr line."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from tests import paths

DATA = paths.DATA / "arcos"
ROBOCLI = [sys.executable, "-m", "robocli"]


def run(*args: str, timeout: float = 60, **kwargs: object) -> subprocess.CompletedProcess[str]:
    """``robocli ARGS`` to completion, stdin closed, output captured as text."""
    return subprocess.run(
        [*ROBOCLI, *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        stdin=subprocess.DEVNULL,
        **kwargs,  # type: ignore[arg-type]
    )


def one_line_error(proc: subprocess.CompletedProcess[str], code: int) -> str:
    """The single ``robocli: ...`` stderr line of a process that exited with ``code``."""
    assert proc.returncode == code, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("robocli: "), proc.stderr
    assert "Traceback" not in proc.stderr
    return lines[0]


@contextlib.contextmanager
def running(*args: str, **kwargs: object) -> Iterator[subprocess.Popen[str]]:
    """``robocli ARGS`` in the background (stdout and stderr piped); killed if still
    running when the block ends."""
    proc = subprocess.Popen(
        [*ROBOCLI, *args],
        stdout=kwargs.pop("stdout", subprocess.PIPE),  # type: ignore[arg-type]
        stderr=subprocess.PIPE,
        stdin=kwargs.pop("stdin", subprocess.DEVNULL),  # type: ignore[arg-type]
        text=True,
        **kwargs,  # type: ignore[arg-type]
    )
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait(10)
        for stream in (proc.stdout, proc.stderr):
            if stream is not None:
                stream.close()


def ctrl_c(proc: subprocess.Popen[str], timeout: float = 30.0) -> tuple[str, str]:
    """Ctrl-C to a running ``robocli``: its stdout and stderr once it ended (killed if it
    has not within ``timeout``, which only bounds a failure)."""
    proc.send_signal(signal.SIGINT)
    try:
        return proc.communicate(timeout=timeout)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout)


def read_lines(stream: IO[str], n: int, timeout: float = 30.0) -> list[str]:
    """The first ``n`` lines of a child's ``stream`` (fewer if it ends or ``timeout`` passes,
    which only bounds a failure): wait for output, not for a time that a loaded machine
    stretches."""
    lines: list[str] = []

    def read() -> None:
        for line in stream:
            lines.append(line)
            if len(lines) >= n:
                return

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    reader.join(timeout)
    return list(lines)


def peak_rss_kib(pid: int) -> int:
    """Peak resident memory of a running process (Linux ``VmHWM``), KiB."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1])
    raise AssertionError("no VmHWM in /proc status")


def bytes_read(pid: int) -> int:
    """Bytes a running process has read so far (Linux ``/proc/PID/io`` rchar)."""
    for line in Path(f"/proc/{pid}/io").read_text().splitlines():
        if line.startswith("rchar:"):
            return int(line.split()[1])
    raise AssertionError("no rchar in /proc io")


def env_without_rich_width(columns: int = 80, lines: int = 24) -> dict[str, str]:
    """The environment with a terminal of ``columns`` x ``lines``."""
    return {**os.environ, "COLUMNS": str(columns), "LINES": str(lines), "TERM": "xterm"}
