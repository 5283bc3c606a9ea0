"""robocli's serial stream (an extension of ros4mat) end to end over real sockets and ptys: a
:class:`VirtualSerial` and a pty relay to a hub whose serial port is a pty, the token and the
allow-list, bounded writes with deadlines, the hub restarting."""

from __future__ import annotations

import os
import socket
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest

from robocli.devices.hub.relay import PtyRelay
from robocli.devices.hub.serial import VirtualSerial
from robocli.errors import ConnectionLost, DeviceError
from robocli.hub_server import HubServer
from robocli.protocols import ros4mat as r4m
from tests.devices.hub.serial_device import TIMEOUT, Device, device_fixture, duplex  # noqa: F401
from tests.waiting import wait_for

pytestmark = pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs pseudo-terminals")

TOKEN = b"lab-secret"


@pytest.fixture
def hub(device: Device) -> Iterator[HubServer]:
    with HubServer(port=0, sim=False, serial_ports=[device.path], token=TOKEN) as srv:
        yield srv


def _address(srv: HubServer) -> str:
    return f"127.0.0.1:{srv.port}"


def reader(line: VirtualSerial) -> Callable[[int, float], bytes]:
    def read(n: int, timeout: float) -> bytes:
        end, got = time.monotonic() + timeout, bytearray()
        while len(got) < n and time.monotonic() < end:
            got += line.read(n - len(got), timeout=max(0.0, end - time.monotonic()))
        return bytes(got)

    return read


# ---------------------------------------------------------------------------- streaming


def test_bytes_both_ways_in_order_at_115200(device: Device, hub: HubServer) -> None:
    with VirtualSerial.open(_address(hub), device.path, baudrate=115200, token=TOKEN) as line:
        up, got_up, down, got_down = duplex(line.write, reader(line), device, seconds=2.0)
    assert got_up == up and got_down == down  # neither lost nor reordered, both ways
    assert line.overflowed == 0


def test_settings_reach_the_hubs_port(device: Device, hub: HubServer) -> None:
    import termios

    with VirtualSerial.open(_address(hub), device.path, baudrate=19200, token=TOKEN) as line:
        assert device.settings()[5] == termios.B19200
        line.configure(baudrate=115200, stopbits=2)
        attrs = device.settings()
        assert attrs[5] == termios.B115200 and attrs[2] & termios.CSTOPB
        line.write(b"after")
        assert device.wait_bytes(5) == b"after"


def test_serial_cmd_on_a_streamed_port_is_busy(device: Device, hub: HubServer) -> None:
    from robocli import Hub

    with VirtualSerial.open(_address(hub), device.path, token=TOKEN), \
            Hub.connect(_address(hub), token=TOKEN) as client:  # fmt: skip
        with pytest.raises(DeviceError, match="busy: another client streams it|streams it"):
            client.serial(device.path, b"x")
        with pytest.raises(DeviceError, match="busy"):
            VirtualSerial.open(_address(hub), device.path, token=TOKEN)
    with Hub.connect(_address(hub), token=TOKEN) as client:  # the stream gave it back
        assert client.serial(device.path, b"ok") == b""
    assert device.wait_bytes(2) == b"ok"


# ---------------------------------------------------------------------------- refusals


def test_refusals_are_device_errors(device: Device, hub: HubServer) -> None:
    with pytest.raises(DeviceError, match="unauthorized: SERIAL_OPEN needs the hub's token"):
        VirtualSerial.open(_address(hub), device.path)
    with pytest.raises(DeviceError, match="unauthorized"):
        VirtualSerial.open(_address(hub), device.path, token=b"wrong")
    with pytest.raises(DeviceError, match="'/dev/ttyS77' is not served by this hub"):
        VirtualSerial.open(_address(hub), "/dev/ttyS77", token=TOKEN)
    with HubServer(port=0, sim=False, serial_ports=["/dev/robocli-no-such-tty"]) as srv:
        with pytest.raises(DeviceError, match="cannot be opened on the hub"):
            VirtualSerial.open(_address(srv), "/dev/robocli-no-such-tty")
    with HubServer(port=0, sim=False) as srv:
        with pytest.raises(DeviceError, match="serves no serial port|not served"):
            VirtualSerial.open(_address(srv), device.path)


def _raw_open(port: int, path: str) -> socket.socket:
    sock = socket.create_connection(("127.0.0.1", port), timeout=TIMEOUT)
    hello = r4m.encode_request(r4m.MsgType.CONNECT, {"protocol_version": 3, "compression": 0})
    sock.sendall(r4m.encode_request(r4m.MsgType.CONNECT, hello[r4m.HEADER_SIZE :] + TOKEN))
    assert _recv(sock).msg_type == r4m.MsgType.CONNECT_ACK
    body = {"speed": 115200, "byte_size": 8, "parity": "N", "stop_bits": 10, "port": path}
    sock.sendall(r4m.encode_request(r4m.MsgType.SERIAL_OPEN, body))
    ack = _recv(sock)
    assert ack.msg_type == r4m.MsgType.SERIAL_OPEN_ACK and not ack.error, ack
    return sock


def _recv(sock: socket.socket) -> r4m.DecodedPacket:
    def exact(n: int) -> bytes:
        buf = b""
        while len(buf) < n:
            piece = sock.recv(n - len(buf))
            assert piece, "closed"
            buf += piece
        return buf

    head = exact(r4m.HEADER_SIZE)
    return r4m.decode(head + exact(r4m.body_length(r4m.Header.parse(head))))


def test_a_write_is_bounded(device: Device, hub: HubServer) -> None:
    sock = _raw_open(hub.port, device.path)
    with sock:
        too_big = b"x" * (r4m.MAX_STREAM_CHUNK + 1)
        sock.sendall(r4m.encode_request(r4m.MsgType.SERIAL_WRITE, too_big))
        reply = _recv(sock)
        assert reply.msg_type == r4m.MsgType.SERIAL_WRITE and reply.error
        assert "1..4096 bytes" in (reply.error_text or "")
        sock.sendall(r4m.encode_request(r4m.MsgType.SERIAL_WRITE, b"fits"))
        assert device.wait_bytes(4) == b"fits"


def test_a_write_the_line_does_not_take_misses_its_deadline(device: Device, hub: HubServer
                                                          ) -> None:  # fmt: skip
    """A device that stops reading: the hub's write to its port ends at its deadline with an
    error, the stream closes and the port is given back; the client's line ends with it."""
    device.pause()
    line = VirtualSerial.open(_address(hub), device.path, baudrate=115200, token=TOKEN)
    with line:
        chunk = bytes(r4m.MAX_STREAM_CHUNK)
        with pytest.raises((DeviceError, ConnectionLost)):
            end = time.monotonic() + 60
            while time.monotonic() < end:  # until the pty's buffer is full and one misses
                line.write(chunk)
                line.read(1, timeout=0)  # raises once the hub said the write failed
        assert isinstance(line.ended, DeviceError) and "write failed" in str(line.ended)
    wait_for(lambda: hub.serial is not None and not hub.serial._streamed, "the port given back")


# ---------------------------------------------------------------------------- the pty


def test_a_pyserial_program_on_the_pty(device: Device, hub: HubServer) -> None:
    """The program opens the relay's pty as a serial port and sets its own settings: they
    reach the hub's port before its bytes, and bytes go both ways."""
    import termios

    import serial

    with PtyRelay(_address(hub), device.path, token=TOKEN) as relay:
        stop = threading.Event()
        runner = threading.Thread(target=relay.run, args=(stop,), daemon=True)
        runner.start()
        try:
            with serial.Serial(relay.path, 115200, stopbits=2, timeout=TIMEOUT) as program:
                program.write(b"\x80\x83")  # START, SAFE
                assert device.wait_bytes(2) == b"\x80\x83"
                attrs = device.settings()  # set on the hub's port before the bytes came
                assert attrs[5] == termios.B115200 and attrs[2] & termios.CSTOPB
                device.write(b"\x13\x05ok")
                assert program.read(4) == b"\x13\x05ok"
                up, got_up, down, got_down = duplex(
                    program.write, lambda n, t: program.read(n), device, seconds=1.0
                )
                assert device.got[2:] == up and got_down == down
        finally:
            stop.set()
            runner.join(TIMEOUT)


def test_pyserial_url_handler(device: Device, hub: HubServer, tmp_path: Any) -> None:
    import serial

    from robocli.devices.hub.serial_url import register

    register()
    token_file = tmp_path / "token"
    token_file.write_bytes(TOKEN + b"\n")
    url = f"robocli://{_address(hub)}{device.path}?baudrate=115200&token_file={token_file}"
    with serial.serial_for_url(url, timeout=TIMEOUT) as port:
        # no modem line crosses the hub: what a program waits for reads asserted, no ring
        assert (port.cts, port.dsr, port.cd, port.ri) == (True, True, True, False)
        port.write(b"ping")
        assert device.wait_bytes(4) == b"ping"
        device.write(b"pong")
        assert port.read(4) == b"pong"
        port.baudrate = 57600
        import termios

        assert device.settings()[5] == termios.B57600
    with pytest.raises(serial.SerialException, match="unauthorized"):
        serial.serial_for_url(f"robocli://{_address(hub)}{device.path}")


def test_an_unmodified_pyserial_program_run_with_the_handler(device: Device, hub: HubServer,
                                                            tmp_path: Any) -> None:  # fmt: skip
    """``python -m robocli.devices.hub.serial_url PROGRAM URL``: the program opens its port
    with ``serial.serial_for_url`` and knows nothing of robocli; only its port string says
    ``robocli://`` (the token from ``$ROBOCLI_HUB_TOKEN_FILE``)."""
    import subprocess
    import sys

    program = tmp_path / "program.py"
    program.write_text(
        "import sys, serial\n"
        "port = serial.serial_for_url(sys.argv[1], baudrate=115200, timeout=10)\n"
        "port.write(b'hello')\n"
        "print(port.read(3).decode())\n"
        "port.close()\n"
    )
    token_file = tmp_path / "token"
    token_file.write_bytes(TOKEN)
    url = f"robocli://{_address(hub)}{device.path}"
    device.echo = True
    run = subprocess.run(
        [sys.executable, "-m", "robocli.devices.hub.serial_url", str(program), url],
        capture_output=True, text=True, timeout=60,
        env={**os.environ, "ROBOCLI_HUB_TOKEN_FILE": str(token_file)},
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "hel" and device.wait_bytes(5) == b"hello"


# ---------------------------------------------------------------------------- restarts


def test_the_line_survives_the_hub_restarting(device: Device) -> None:
    events: list[tuple[str, str]] = []
    srv = HubServer(port=0, sim=False, serial_ports=[device.path], token=TOKEN).start()
    port = srv.port
    line = VirtualSerial.open(f"127.0.0.1:{port}", device.path, token=TOKEN,
                              on_event=lambda k, t: events.append((k, t)))  # fmt: skip
    try:
        line.write(b"one")
        assert device.wait_bytes(3) == b"one"
        srv.close()
        wait_for(lambda: "lost" in [k for k, _ in events], "the line to say it lost the hub")
        srv = HubServer(port=port, sim=False, serial_ports=[device.path], token=TOKEN).start()
        wait_for(lambda: line.connected and line.resumes == 1, "the line to come back")
        assert [k for k, _ in events] == ["lost", "resumed"]
        line.write(b"two")
        assert device.wait_bytes(6) == b"onetwo"
        device.write(b"back")
        assert reader(line)(4, TIMEOUT) == b"back"
    finally:
        line.close()
        srv.close()


def test_the_line_ends_when_the_hub_does_not_come_back(device: Device) -> None:
    events: list[str] = []
    with HubServer(port=0, sim=False, serial_ports=[device.path], token=TOKEN) as srv:
        line = VirtualSerial.open(_address(srv), device.path, token=TOKEN, resume=0.6,
                                  on_event=lambda k, t: events.append(k))  # fmt: skip
    with line:
        wait_for(lambda: line.ended is not None, "the line to end")
        assert events == ["lost", "ended"]
        with pytest.raises(ConnectionLost, match="did not come back in 0.6 s"):
            line.read(1, timeout=1)
        with pytest.raises(ConnectionLost):
            line.write(b"x")


# ---------------------------------------------------------------------------- soak


@pytest.mark.slow
def test_soak_both_ways_at_115200_through_the_pty(device: Device, hub: HubServer) -> None:
    """``make soak-serial``: SOAK_SERIAL_S seconds (default 600) of bytes both ways at
    115200 baud from a program on the relay's pty to the device on the hub's port."""
    import serial

    seconds = float(os.environ.get("SOAK_SERIAL_S", "600"))
    with PtyRelay(_address(hub), device.path, token=TOKEN) as relay:
        stop = threading.Event()
        runner = threading.Thread(target=relay.run, args=(stop,), daemon=True)
        runner.start()
        try:
            with serial.Serial(relay.path, 115200, timeout=seconds + TIMEOUT) as program:
                up, got_up, down, got_down = duplex(
                    program.write, lambda n, t: program.read(n), device, seconds=seconds
                )
        finally:
            stop.set()
            runner.join(TIMEOUT)
    assert len(got_up) == len(up) and got_up == up
    assert len(got_down) == len(down) and got_down == down
    assert relay.dropped == 0 and relay.line is not None and relay.line.overflowed == 0
