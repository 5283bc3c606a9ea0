"""``robocli serial HUB PORT --pty`` as a user runs it: the pty's path on stdout, bytes both
ways, one line and the README's exit code for each refusal, the hub restarting, Ctrl-C."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

from robocli.hub_server import HubServer
from tests.commands.helpers import one_line_error, read_lines, run, running
from tests.devices.hub.serial_device import TIMEOUT, Device, device_fixture  # noqa: F401

pytestmark = pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs pseudo-terminals")


@pytest.fixture
def token_file(tmp_path: Path) -> Path:
    path = tmp_path / "hub.token"
    path.write_text("s3cret\n")
    return path


def test_refusals_are_one_line_each(device: Device, token_file: Path) -> None:
    with HubServer(port=0, sim=False, token=b"s3cret",
                   serial_ports=[device.path, "/dev/robocli-no-such-tty"]) as srv:  # fmt: skip
        hub = f"127.0.0.1:{srv.port}"
        line = one_line_error(run("serial", hub, device.path, "--pty"), 4)
        assert "unauthorized: SERIAL_OPEN needs the hub's token" in line
        line = one_line_error(run("serial", hub, "/dev/ttyS77", "--pty", "--token-file",
                                  str(token_file)), 4)  # fmt: skip
        assert "'/dev/ttyS77' is not served by this hub" in line
        line = one_line_error(run("serial", hub, "/dev/robocli-no-such-tty", "--pty",
                                  "--token-file", str(token_file)), 4)  # fmt: skip
        assert "cannot be opened on the hub" in line
        line = one_line_error(run("serial", hub, device.path, "--pty", "--send", "x"), 2)
        assert "--pty relays until Ctrl-C" in line
        line = one_line_error(run("serial", hub, device.path, "--zenoh", "lab.json5"), 2)
        assert "--zenoh goes with --pty" in line
        port = srv.port
    line = one_line_error(run("serial", f"127.0.0.1:{port}", device.path, "--pty"), 3)
    assert "no hub at 127.0.0.1" in line


def test_pty_relays_and_survives_a_hub_restart(device: Device, token_file: Path) -> None:
    import serial

    srv = HubServer(port=0, sim=False, serial_ports=[device.path], token=b"s3cret").start()
    port = srv.port
    try:
        with running("serial", f"127.0.0.1:{port}", device.path, "--pty", "--token-file",
                     str(token_file)) as proc:  # fmt: skip
            assert proc.stdout is not None and proc.stderr is not None
            (path,) = read_lines(proc.stdout, 1)
            with serial.Serial(path.strip(), 115200, timeout=TIMEOUT) as program:
                program.write(b"one")
                assert device.wait_bytes(3) == b"one"
                srv.close()
                (lost,) = read_lines(proc.stderr, 1)
                assert lost.startswith("robocli: hub lost (") and "reconnecting" in lost
                srv = HubServer(port=port, sim=False, serial_ports=[device.path],
                                token=b"s3cret").start()  # fmt: skip
                (back,) = read_lines(proc.stderr, 1)
                assert back.startswith("robocli: hub back: ") and back.endswith("resumed\n")
                program.write(b"two")
                assert device.wait_bytes(6) == b"onetwo"
                device.write(b"back")
                assert program.read(4) == b"back"
            proc.send_signal(signal.SIGINT)
            assert proc.wait(TIMEOUT) == 130
            assert proc.stderr.read().splitlines() == ["robocli: interrupted"]
    finally:
        srv.close()
