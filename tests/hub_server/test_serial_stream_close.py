"""A streamed serial port closed under its reader (the hub shutting down closes every port,
the streams' too): the stream ends, reported once, without an exception escaping its thread."""

from __future__ import annotations

import os
import select
import threading
from typing import Any

import pytest

from robocli.hub_server.serial import SerialStream
from robocli.hub_server.sources import SerialPorts
from tests.devices.hub.serial_device import Device, device_fixture  # noqa: F401

pytestmark = pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs pseudo-terminals")


def test_a_port_closed_under_its_reader_ends_the_stream_quietly(
        device: Device, monkeypatch: pytest.MonkeyPatch) -> None:  # fmt: skip
    escaped: list[Any] = []
    monkeypatch.setattr(threading, "excepthook", escaped.append)
    stop = threading.Event()

    def chatter() -> None:  # the device talks all the time: the reader is mostly reading
        while not stop.is_set():
            if select.select([], [device.master], [], 0.05)[1]:
                os.write(device.master, b"x" * 64)

    talker = threading.Thread(target=chatter, daemon=True)
    talker.start()
    try:
        for _ in range(30):
            ports = SerialPorts([device.path])
            got = threading.Event()
            failed: list[str] = []
            stream = SerialStream(ports, device.path, {"baudrate": 115200},
                                  lambda data, got=got: got.set() or True,
                                  failed.append)  # fmt: skip
            assert got.wait(10)
            ports.close()  # under the reader, as a hub's shutdown does
            stream._reader.join(10)
            assert not stream._reader.is_alive()
            stream.close()
            assert len(failed) <= 1
    finally:
        stop.set()
        talker.join(5)
    assert escaped == []
