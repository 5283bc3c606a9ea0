"""SERIAL_CMD passthrough to a local serial port (a pty pair), restricted to allowed ports."""

from __future__ import annotations

import os
import select
from collections.abc import Iterator
from typing import Any

import pytest

from robocli.hub_server import HubServer
from robocli.protocols import ros4mat as r4m

pytestmark = pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs pseudo-terminals")


@pytest.fixture
def pty_pair() -> Iterator[tuple[int, str]]:
    master, slave = os.openpty()
    path = os.ttyname(slave)
    yield master, path
    os.close(master)
    os.close(slave)


def _serial_cmd(port: str, data: bytes, recv: int, *, timeout_s: int = 2, close: int = 0) -> Any:
    cmd = {"port_length": len(port), "speed": 115200, "parity": 0, "stop_bits": 1,
           "send_length": len(data), "read_length": recv, "read_timeout_sec": timeout_s,
           "read_timeout_usec": 0, "close_after": close}  # fmt: skip
    return {"cmd": cmd, "port": port.encode(), "data": data}


def _read(fd: int, n: int, timeout: float = 5.0) -> bytes:
    got = b""
    while len(got) < n:
        ready, _, _ = select.select([fd], [], [], timeout)
        if not ready:
            break
        got += os.read(fd, n - len(got))
    return got


def test_serial_passthrough_over_a_pty(pty_pair: tuple[int, str], raw: Any) -> None:
    master, path = pty_pair
    with HubServer(port=0, serial_ports=[path]) as srv:
        c = raw(srv.port)
        c.connect()
        # open (raw mode, no echo) and flush: sendLen = recvLen = 0
        reply = c.request(r4m.MsgType.SERIAL_CMD, _serial_cmd(path, b"", 0))
        assert reply.body["ans"] == {"status": 0, "data_length": 0}
        os.write(master, b"world")  # the device's answer, waiting in the line
        reply = c.request(r4m.MsgType.SERIAL_CMD, _serial_cmd(path, b"hello", 5))
        assert _read(master, 5) == b"hello"
        assert reply.msg_type == r4m.MsgType.SERIAL_ANS and reply.error == 0
        assert reply.body == {"ans": {"status": 0, "data_length": 5}, "data": b"world"}
        # nothing to read: a timeout status with what arrived (nothing)
        reply = c.request(r4m.MsgType.SERIAL_CMD, _serial_cmd(path, b"", 3, timeout_s=0))
        assert reply.body["ans"]["status"] == r4m.SerialStatus.TIMEOUT
        reply = c.request(r4m.MsgType.SERIAL_CMD, _serial_cmd(path, b"bye", 0, close=1))
        assert reply.body["ans"] == {"status": 0, "data_length": 0}
        assert _read(master, 3) == b"bye"
        assert srv.serial is not None and not srv.serial.open_ports  # close_after closed it
        c.close()


def test_serial_ports_not_listed_are_refused(pty_pair: tuple[int, str], raw: Any) -> None:
    _, path = pty_pair
    with HubServer(port=0, serial_ports=[path]) as srv:
        c = raw(srv.port)
        c.connect()
        reply = c.request(r4m.MsgType.SERIAL_CMD, _serial_cmd("/dev/ttyS0", b"x", 1))
        assert reply.msg_type == r4m.MsgType.SERIAL_ANS and "not served" in reply.error_text
        c.close()
    with HubServer(port=0) as srv:  # no --serial at all
        c = raw(srv.port)
        c.connect()
        reply = c.request(r4m.MsgType.SERIAL_CMD, _serial_cmd(path, b"x", 1))
        assert "no serial port" in reply.error_text
        c.close()


def test_serial_needs_the_token_when_set(pty_pair: tuple[int, str], raw: Any) -> None:
    master, path = pty_pair
    with HubServer(port=0, serial_ports=[path], token=b"k") as srv:
        c = raw(srv.port)
        c.connect()
        reply = c.request(r4m.MsgType.SERIAL_CMD, _serial_cmd(path, b"x", 0))
        assert "unauthorized" in reply.error_text
        c.connect(token=b"k", client_id=c.client_id)
        reply = c.request(r4m.MsgType.SERIAL_CMD, _serial_cmd(path, b"ok", 0))
        assert reply.error == 0 and _read(master, 2) == b"ok"
        c.close()
