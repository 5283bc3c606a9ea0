"""A hub's serial port streamed over Zenoh behind the lab's router and its access control
(examples/lab-router.json5): the hub ``hub1`` serves a pty as its serial port; ``alice``
streams it with the hub's token; ``bob``, with valid lab credentials, cannot write into
alice's stream (the router drops his puts on her keys), cannot take the port while she holds
it, and gets nothing without the token; the allow-list holds over Zenoh as over ros4mat."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from typing import Any

import pytest

from robocli.devices.hub.zenoh_serial import ZenohSerialLine
from robocli.errors import DeviceError
from robocli.hub_server import HubServer
from robocli.hub_server.frontends.zenoh import ZenohFrontend
from robocli.zenoh.keys import serial_key
from tests.devices.hub.serial_device import TIMEOUT, Device, device_fixture  # noqa: F401
from tests.waiting import wait_for
from tests.zenoh.test_lab_acl import Lab, lab  # noqa: F401 - the lab fixture

pytest.importorskip("zenoh", reason="needs robocli-robots[zenoh] (eclipse-zenoh)")

TOKEN = b"lab-token"


@pytest.fixture
def hub1(lab: Lab, device: Device) -> Iterator[ZenohFrontend]:  # noqa: F811
    session = lab.session("hub1")
    srv = HubServer(port=0, sim=False, serial_ports=[device.path], token=TOKEN)
    front = ZenohFrontend(srv.hub, session, "hub1", token=TOKEN, serial=srv.serial).start()
    try:
        yield front
    finally:
        front.close()
        srv.close()
        session.close()


class Got:
    def __init__(self) -> None:
        self.data = bytearray()
        self.cond = threading.Condition()

    def __call__(self, data: bytes) -> None:
        with self.cond:
            self.data += data
            self.cond.notify_all()

    def wait(self, n: int) -> bytes:
        with self.cond:
            self.cond.wait_for(lambda: len(self.data) >= n, TIMEOUT)
            return bytes(self.data[:n])


def _line(lab: Lab, user: str, port: str, **kw: Any) -> ZenohSerialLine:  # noqa: F811
    return ZenohSerialLine.open("hub1", port, zenoh=str(lab.configs[user]), **kw)


def test_alice_streams_bob_cannot_write_into_it(lab: Lab, hub1: ZenohFrontend,  # noqa: F811
                                                device: Device) -> None:  # fmt: skip
    got = Got()
    with _line(lab, "alice", device.path, on_data=got, token=TOKEN, baudrate=115200) as line:
        line.write(b"\x80\x83")
        assert device.wait_bytes(2) == b"\x80\x83"
        device.write(b"reply")
        assert got.wait(5) == b"reply"
        bob = lab.session("bob")
        try:  # bob's put on alice's key: the router drops it
            bob.put(serial_key("hub1", "alice", "serial-write"), b"EVIL")
            # then one on his own key, which reaches the hub (no stream of his: dropped and
            # counted) after the first, had the router let that one through
            bob.put(serial_key("hub1", "bob", "serial-write"), b"mine")
            assert hub1.serial is not None
            wait_for(lambda: hub1.serial is not None and hub1.serial.dropped_writes == 1,
                     "bob's own put to reach the hub")  # fmt: skip
            with pytest.raises(DeviceError, match="busy: another client streams it"):
                _line(lab, "bob", device.path, on_data=Got(), token=TOKEN)
        finally:
            bob.close()
        line.write(b"ok")
        assert device.wait_bytes(4) == b"\x80\x83ok"
        assert b"EVIL" not in device.got
    wait_for(lambda: hub1.serial is not None and not hub1.serial._streams, "stream ended")


def test_token_and_allow_list_over_zenoh(lab: Lab, hub1: ZenohFrontend,  # noqa: F811
                                         device: Device) -> None:  # fmt: skip
    with pytest.raises(DeviceError, match="unauthorized: serial-open needs the hub's token"):
        _line(lab, "alice", device.path, on_data=Got())
    with pytest.raises(DeviceError, match="'/dev/ttyS77' is not served by this hub"):
        _line(lab, "alice", "/dev/ttyS77", on_data=Got(), token=TOKEN)
    assert hub1.serial is not None and hub1.serial.refused == 2


def test_a_program_on_the_pty_through_zenoh(lab: Lab, hub1: ZenohFrontend,  # noqa: F811
                                            device: Device) -> None:  # fmt: skip
    import termios

    import serial

    from robocli.devices.hub.relay import PtyRelay

    with PtyRelay("hub1", device.path, zenoh=str(lab.configs["alice"]), token=TOKEN) as relay:
        stop = threading.Event()
        runner = threading.Thread(target=relay.run, args=(stop,), daemon=True)
        runner.start()
        try:
            with serial.Serial(relay.path, 115200, timeout=TIMEOUT) as program:
                program.write(b"\x80\x83")
                assert device.wait_bytes(2) == b"\x80\x83"
                assert device.settings()[5] == termios.B115200
                device.write(b"back")
                assert program.read(4) == b"back"
        finally:
            stop.set()
            runner.join(TIMEOUT)


def test_the_line_resumes_when_the_hub_comes_back(lab: Lab, device: Device) -> None:  # noqa: F811
    events: list[str] = []

    def start() -> tuple[Any, HubServer, ZenohFrontend]:
        session = lab.session("hub1")
        srv = HubServer(port=0, sim=False, serial_ports=[device.path], token=TOKEN)
        return session, srv, ZenohFrontend(srv.hub, session, "hub1", token=TOKEN,
                                           serial=srv.serial).start()  # fmt: skip

    def stop(parts: tuple[Any, HubServer, ZenohFrontend]) -> None:
        parts[2].close()
        parts[1].close()
        parts[0].close()

    hub = start()
    got = Got()
    line = _line(lab, "alice", device.path, on_data=got, token=TOKEN,
                 on_event=lambda kind, text: events.append(kind))  # fmt: skip
    try:
        line.write(b"one")
        assert device.wait_bytes(3) == b"one"
        stop(hub)
        wait_for(lambda: events == ["lost"], "the line to say the hub left")
        hub = start()
        wait_for(lambda: line.connected, "the line to come back")
        assert events == ["lost", "resumed"] and line.resumes == 1
        line.write(b"two")
        assert device.wait_bytes(6) == b"onetwo"
        device.write(b"back")
        assert got.wait(4) == b"back"
    finally:
        line.close()
        stop(hub)
