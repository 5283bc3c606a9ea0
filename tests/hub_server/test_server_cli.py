"""``robocli serve``: a real process, a raw client, Ctrl-C; usage errors exit 2."""

from __future__ import annotations

import os
import queue
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from robocli.cli import main
from tests.commands.helpers import ctrl_c, running

TIMEOUT = 10.0


class Lines:
    """The lines a process prints, read by a thread (no buffering surprises)."""

    def __init__(self, proc: subprocess.Popen[str]) -> None:
        self._queue: queue.Queue[str] = queue.Queue()
        self.seen: list[str] = []
        assert proc.stdout is not None
        stream = proc.stdout
        threading.Thread(target=lambda: [self._queue.put(x) for x in stream], daemon=True).start()

    def until(self, needle: str, timeout: float = TIMEOUT) -> str:
        """The first line (printed so far or within ``timeout``) containing ``needle``."""
        for line in self.seen:
            if needle in line:
                return line
        end = time.monotonic() + timeout
        while (left := end - time.monotonic()) > 0:
            try:
                line = self._queue.get(timeout=left)
            except queue.Empty:
                break
            self.seen.append(line)
            if needle in line:
                return line
        raise AssertionError(f"{needle!r} not in {self.seen}")


def test_serve_sim_logs_clients_and_stops_on_ctrl_c(raw: Any) -> None:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    with running("serve", "--sim", "--port", "0", env=env) as proc:
        lines = Lines(proc)
        first = lines.until("hub serving ", 30.0)  # interpreter start-up under load
        assert "adc" in first, first
        port = int(first.rsplit(":", 1)[1])
        c = raw(port)
        cid = c.connect()
        params = {"freq_acquisition": 100, "freq_send": 35, "channels": 255}
        assert c.subscribe("adc", params, buffer=100).error == 0
        # the status may show the client before its subscription: wait for the line that has it
        assert f"client {cid} " in lines.until("adc[100]")
        lines.until("sensor adc: 100 Hz")
        c.close()
        lines.until("detached")
        out, err = ctrl_c(proc, TIMEOUT)
    assert proc.returncode == 130 and err.strip().splitlines()[-1] == "robocli: interrupted", err


def test_serve_usage_errors_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    empty = tmp_path / "token"
    empty.write_text("\n")
    assert main(["serve", "--port", "0", "--token-file", str(empty)]) == 2
    assert "empty" in capsys.readouterr().err
    assert main(["serve", "--port", "0", "--gpsd", "host:notaport"]) == 2
    assert "port" in capsys.readouterr().err
    assert main(["serve", "--port", "0", "--token-file", str(tmp_path / "none")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "cannot read" in err
    for url in ("bogus://x", "tcp://host", "tcp://host:99999"):  # never works: refused now
        assert main(["serve", "--port", "0", "--pioneer", url]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and "pioneer" in err, err


def test_a_pioneer_url_is_checked_when_the_hub_is_made() -> None:
    from robocli.errors import InvalidArgument
    from robocli.hub_server import HubServer

    with pytest.raises(InvalidArgument, match="unknown URL scheme 'bogus'"):
        HubServer(port=0, sim=True, pioneer="bogus://x")
    HubServer(port=0, sim=False, pioneer="tcp://127.0.0.1:1").close()  # away: retried later


def test_serve_says_which_sensors_the_pioneer_replaces() -> None:
    with running("serve", "--sim", "--port", "0", "--pioneer", "tcp://127.0.0.1:1",
                 env={**os.environ, "PYTHONUNBUFFERED": "1"}) as proc:  # fmt: skip
        Lines(proc).until("hub serving ", 30.0)
        _, err = ctrl_c(proc, TIMEOUT)
    assert "adc and battery: from the Pioneer at tcp://127.0.0.1:1" in err, err


@pytest.mark.skipif(shutil.which("script") is None, reason="needs script(1) for a terminal")
def test_serve_on_a_terminal_shows_a_live_table() -> None:
    cmd = f"{sys.executable} -m robocli serve --sim --port 0"
    proc = subprocess.Popen(
        ["script", "-qfec", cmd, "/dev/null"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
        env={**os.environ, "COLUMNS": "120", "TERM": "xterm"},
    )  # fmt: skip
    try:
        lines = Lines(proc)
        lines.until("hub serving", 30.0)
        lines.until("sensor camera")  # a table row, drawn by Rich
        os.killpg(proc.pid, signal.SIGINT)
        proc.wait(TIMEOUT)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(TIMEOUT)
    assert any("robocli hub on tcp://" in line for line in lines.seen)


def test_a_token_file_is_read_in_bounded_memory(tmp_path: Path) -> None:
    """A token file is short; one that never ends (here /dev/zero) is refused, not read."""
    import typer

    from robocli.commands.serve import token_from_file

    endless = tmp_path / "token"
    endless.symlink_to("/dev/zero")
    with pytest.raises(typer.BadParameter, match="more than a token"):
        token_from_file(endless)
    short = tmp_path / "short"
    short.write_bytes(b"s3cret\n")
    assert token_from_file(short) == b"s3cret"
