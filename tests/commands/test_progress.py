"""A long command shows its progress on a terminal and stays quiet in a pipe: ``record``
rewrites one status line (messages, bytes, rate) on a terminal's stderr."""

from __future__ import annotations

import contextlib
import os
import pty
import select
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from tests.commands.helpers import ROBOCLI, run


@contextlib.contextmanager
def _on_a_terminal(
    args: list[str], terminal: str, **streams: Any
) -> Iterator[tuple[subprocess.Popen[bytes], int]]:
    """``robocli ARGS`` whose ``terminal`` stream ("stdin", "stderr") is a pty, the others
    ``streams``: the process and the pty's master end (the process killed if still running,
    and the master closed, at the end)."""
    master, slave = pty.openpty()
    proc = subprocess.Popen([*ROBOCLI, *args], **{terminal: slave}, **streams)
    os.close(slave)
    try:
        yield proc, master
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
        os.close(master)


def test_record_shows_progress_on_a_terminal(tmp_path: Path) -> None:
    seen = b""
    deadline = time.monotonic() + 120
    with _on_a_terminal(["record", "--pioneer", "sim", "-n", "400", "-o", str(tmp_path / "r.mcap")],
                        "stderr", stdin=subprocess.DEVNULL,
                        stdout=subprocess.DEVNULL) as (proc, master):  # fmt: skip
        while b"msg/s" not in seen and time.monotonic() < deadline:
            ready, _, _ = select.select([master], [], [], 1.0)
            if ready:
                try:
                    seen += os.read(master, 4096)
                except OSError:  # the child closed its end
                    break
        assert proc.wait(120) == 0
    assert b"messages, " in seen and b"msg/s" in seen, seen


def test_record_is_quiet_in_a_pipe(tmp_path: Path) -> None:
    proc = run("record", "--pioneer", "sim", "-n", "400", "-o", str(tmp_path / "r.mcap"))
    assert proc.returncode == 0, proc.stderr
    assert "msg/s" not in proc.stderr and "\x1b" not in proc.stderr


def test_q_quits_connect_arm_as_it_quits_the_pioneers_view() -> None:
    with _on_a_terminal(["connect", "arm", "sim"], "stdin", stdout=subprocess.PIPE,
                        stderr=subprocess.PIPE) as (proc, master):  # the view reads keys
        assert proc.stdout is not None
        assert "tcp" in proc.stdout.readline().decode()  # the view runs
        os.write(master, b"q")
        assert proc.wait(60) == 0
