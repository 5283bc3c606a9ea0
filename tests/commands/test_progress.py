"""A long command shows its progress on a terminal and stays quiet in a pipe: ``record``
rewrites one status line (messages, bytes, rate) on a terminal's stderr."""

from __future__ import annotations

import os
import pty
import select
import subprocess
import time
from pathlib import Path

from tests.commands.helpers import ROBOCLI, run


def test_record_shows_progress_on_a_terminal(tmp_path: Path) -> None:
    master, slave = pty.openpty()
    proc = subprocess.Popen([*ROBOCLI, "record", "--pioneer", "sim", "-n", "400", "-o",
                             str(tmp_path / "r.mcap")], stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=slave)  # fmt: skip
    os.close(slave)
    seen = b""
    deadline = time.monotonic() + 120
    try:
        while b"msg/s" not in seen and time.monotonic() < deadline:
            ready, _, _ = select.select([master], [], [], 1.0)
            if ready:
                try:
                    seen += os.read(master, 4096)
                except OSError:  # the child closed its end
                    break
        assert proc.wait(120) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
        os.close(master)
    assert b"messages, " in seen and b"msg/s" in seen, seen


def test_record_is_quiet_in_a_pipe(tmp_path: Path) -> None:
    proc = run("record", "--pioneer", "sim", "-n", "400", "-o", str(tmp_path / "r.mcap"))
    assert proc.returncode == 0, proc.stderr
    assert "msg/s" not in proc.stderr and "\x1b" not in proc.stderr


def test_q_quits_connect_arm_as_it_quits_the_pioneers_view() -> None:
    master, slave = pty.openpty()  # stdin a terminal: the view reads keys
    proc = subprocess.Popen([*ROBOCLI, "connect", "arm", "sim"], stdin=slave,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
    os.close(slave)
    try:
        assert proc.stdout is not None
        assert "tcp" in proc.stdout.readline().decode()  # the view runs
        os.write(master, b"q")
        assert proc.wait(60) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
        os.close(master)
