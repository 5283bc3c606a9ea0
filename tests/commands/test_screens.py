"""Terminal screens on a real pseudo-terminal of 80x24: the live view fits, says how to
quit, quits on q, and ends on a fresh line; teleop's status line redraws at >= 5 Hz while
no key is pressed (issue 7: 17)."""

from __future__ import annotations

import fcntl
import os
import re
import select
import signal
import struct
import subprocess
import termios
import time
from collections.abc import Iterator
from contextlib import contextmanager

import pytest

from tests.commands.helpers import ROBOCLI, env_without_rich_width

ANSI = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")


class Terminal:
    """A robocli process on the slave side of a pty of 80x24; one of its output streams is
    a pipe (stderr, or stdout when stderr is on the pty)."""

    def __init__(self, proc: subprocess.Popen[bytes], master: int) -> None:
        self.proc, self.master, self.output = proc, master, b""

    def read_until(self, pattern: bytes, timeout: float = 20.0, count: int = 1) -> None:
        deadline = time.monotonic() + timeout
        while self.output.count(pattern) < count:
            left = deadline - time.monotonic()
            assert left > 0, f"no {pattern!r} x{count} in {self.output[-400:]!r}"
            self.read(min(left, 0.2))

    def read(self, timeout: float) -> None:
        ready, _, _ = select.select([self.master], [], [], timeout)
        if ready:
            try:
                self.output += os.read(self.master, 65536)
            except OSError:  # the child closed the slave side
                time.sleep(0.01)

    def drain(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.read(end - time.monotonic())

    def finish(self, timeout: float = 15.0) -> tuple[int, str]:
        """The exit code and what went to the pipe, reading the terminal meanwhile (a child
        whose terminal output nobody reads would block on it)."""
        deadline = time.monotonic() + timeout
        while self.proc.poll() is None:
            left = deadline - time.monotonic()
            if left <= 0:
                raise subprocess.TimeoutExpired(self.proc.args, timeout)
            self.read(min(left, 0.1))
        self.drain(0.2)
        piped = self.proc.stderr or self.proc.stdout
        assert piped is not None
        return self.proc.returncode, piped.read().decode()

    @property
    def text(self) -> str:
        return ANSI.sub("", self.output.decode(errors="replace"))


@contextmanager
def terminal(*args: str, stderr_on_pty: bool = False) -> Iterator[Terminal]:
    """``robocli ARGS`` with stdin and stdout on the terminal, stderr on a pipe; with
    ``stderr_on_pty``, stderr on the terminal and stdout on the pipe (a bench: progress on
    the terminal, results on stdout)."""
    master, slave = os.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))
    out, err = (subprocess.PIPE, slave) if stderr_on_pty else (slave, subprocess.PIPE)
    proc = subprocess.Popen([*ROBOCLI, *args], stdin=slave, stdout=out, stderr=err,
                            env=env_without_rich_width(80, 24))  # fmt: skip
    os.close(slave)
    try:
        yield Terminal(proc, master)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(10)
        os.close(master)
        for pipe in (proc.stdout, proc.stderr):
            if pipe is not None:
                pipe.close()


def test_live_view_fits_80x24_says_how_to_quit_and_quits_on_q() -> None:
    with terminal("connect", "pioneer", "sim") as term:
        term.read_until(b"q or Ctrl-C quits", count=3)
        os.write(term.master, b"q")
        code, err = term.finish()
    assert code == 0 and err == "", err
    frame = term.text.split("q or Ctrl-C quits")[-2]  # one whole redraw
    lines = re.split(r"[\r\n]+", frame)
    assert max(len(line) for line in lines) <= 80
    assert len([line for line in lines if line.strip()]) + 1 <= 24
    assert "sonar (m)" in frame and "deg/s" in frame
    assert term.output.endswith(b"\n")


@pytest.mark.parametrize("command", [("connect", "pioneer", "sim"), ("teleop", "pioneer", "sim")])
def test_ctrl_c_ends_on_a_fresh_line(command: tuple[str, ...]) -> None:
    marker = b"quits" if command[0] == "connect" else b" V "
    with terminal(*command) as term:
        term.read_until(marker, count=2)
        term.proc.send_signal(signal.SIGINT)
        code, err = term.finish()
    assert code == 130 and err.strip() == "robocli: interrupted", err
    assert term.output.endswith(b"\n"), term.output[-80:]


def test_teleop_status_line_redraws_at_5_hz_or_more() -> None:
    with terminal("teleop", "pioneer", "sim") as term:
        term.read_until(b"\rv ")
        start = term.output.count(b"\rv ")
        began = time.monotonic()
        term.drain(1.5)
        redraws = (term.output.count(b"\rv ") - start) / (time.monotonic() - began)
        os.write(term.master, b"q")
        code, err = term.finish()
    assert redraws >= 5, f"{redraws:.1f} redraws/s"
    assert code == 0 and err == "", err
    status = term.text.rstrip().rsplit("\r", 1)[-1]
    assert "deg/s" in status and "th " in status and len(status.rstrip()) <= 80
