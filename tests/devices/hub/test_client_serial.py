"""The hub's remote serial port through the client and `robocli serial`, over a pty pair."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import tty
from collections.abc import Iterator

import pytest

from robocli import Hub
from robocli.errors import DeviceError
from robocli.hub_server import HubServer
from tests.waiting import run_together


@pytest.fixture
def pty_hub() -> Iterator[tuple[HubServer, str, int]]:
    master, slave = os.openpty()
    tty.setraw(slave)
    name = os.ttyname(slave)
    try:
        with HubServer(bind="127.0.0.1", port=0, sim=True, serial_ports=[name]) as srv:
            yield srv, name, master
    finally:
        os.close(master)
        os.close(slave)


def shouting_device(master: int, n: int) -> threading.Thread:
    """The device on the pty: reads ``n`` bytes, answers them in upper case."""

    def run() -> None:
        data = b""
        while len(data) < n:
            data += os.read(master, 256)
        os.write(master, data.upper())

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


def test_serial_roundtrip_and_refusal(pty_hub: tuple[HubServer, str, int]) -> None:
    srv, name, master = pty_hub
    device = shouting_device(master, 5)
    with Hub.connect("127.0.0.1", srv.port) as hub:
        assert hub.serial(name, b"hello", baud=115200, recv=5, timeout=5.0) == b"HELLO"
        device.join(5)
        with pytest.raises(DeviceError, match="not served"):
            hub.serial("/dev/ttyS99", b"x", recv=1)


def test_serial_cli(pty_hub: tuple[HubServer, str, int]) -> None:
    srv, name, master = pty_hub
    shouting_device(master, 3)
    proc = subprocess.run(
        [sys.executable, "-m", "robocli", "serial", f"127.0.0.1:{srv.port}", name,
         "--baud", "57600", "--send", "616263", "--hex", "--recv", "3", "--timeout", "5"],
        capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "41 42 43"


def test_serial_timeout_range_is_the_hubs_cap() -> None:
    from robocli.commands.serial import SERIAL_MAX_WAIT_S
    from robocli.hub_server.sources.real import MAX_SERIAL_WAIT_S

    assert SERIAL_MAX_WAIT_S == MAX_SERIAL_WAIT_S
    proc = subprocess.run(
        [sys.executable, "-m", "robocli", "serial", "127.0.0.1:1", "/dev/ttyS0", "--timeout",
         str(MAX_SERIAL_WAIT_S + 1)],
        capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL,
    )  # fmt: skip
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "--timeout" in proc.stderr


def test_a_client_queued_behind_others_hears_busy(pty_hub: tuple[HubServer, str, int]) -> None:
    """Commands on the hub's serial ports run one at a time; one that waited
    SERIAL_QUEUE_S for the others gets "busy" rather than no answer at all."""
    srv, name, _master = pty_hub  # nobody answers on the pty: every read waits its timeout
    results: list[object] = []

    def user() -> None:
        with Hub.connect("127.0.0.1", srv.port) as hub:
            try:
                results.append(hub.serial(name, b"?", recv=1, timeout=4.5))
            except DeviceError as exc:
                results.append(exc)

    run_together(user, 3, timeout=30)
    assert len(results) == 3
    assert results.count(b"") == 1, results  # the first: its read timed out, nothing came
    busy = [r for r in results if isinstance(r, DeviceError)]
    assert len(busy) == 2 and all("busy" in str(e) for e in busy), results
