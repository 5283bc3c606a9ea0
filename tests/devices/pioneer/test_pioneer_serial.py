"""Serial links (issue 7, item 5): baud probing, HOSTBAUD after CONFIG, the dialout hint.
Over a real pseudo-terminal served by the built-in simulator (a pty accepts any rate, so
these tests check what the client does with the port and what reaches the robot)."""

from __future__ import annotations

import errno

import pytest

from robocli.devices.pioneer import Pioneer
from robocli.sim.pioneer.server import PioneerSim
from robocli.transports import _serial_hint


def test_hostbaud_after_config_switches_the_port() -> None:
    with PioneerSim("p3dx", time_scale=5.0) as sim:
        path = sim.serve_pty()
        with Pioneer.connect(path, baudrate=9600, switch_baud=38400) as robot:
            assert robot.transport.port.baudrate == 38400  # type: ignore[attr-defined]
            robot.wait_for_sip()
        assert sim.snapshot().commands["HOSTBAUD"] == 1


def test_no_switch_to_a_slower_rate_and_bad_rates_refused() -> None:
    from robocli.errors import InvalidArgument

    with PioneerSim("p3dx", time_scale=5.0) as sim:
        path = sim.serve_pty()
        with Pioneer.connect(path, baudrate=38400, switch_baud=9600) as robot:
            assert robot.transport.port.baudrate == 38400  # type: ignore[attr-defined]
        assert sim.snapshot().commands["HOSTBAUD"] == 0
        with pytest.raises(InvalidArgument, match="baud rate 12345"):
            Pioneer.connect(path, switch_baud=12345)


def test_permission_error_hints_at_the_dialout_group() -> None:
    exc = OSError(errno.EACCES, "could not open port /dev/ttyUSB0: [Errno 13] Permission denied")
    assert "dialout" in _serial_hint(exc)
    assert _serial_hint(OSError(errno.ENOENT, "No such file")) == ""


def test_a_second_client_on_a_serial_robot_is_refused_and_the_first_goes_on() -> None:
    """A pty, like a USB serial port, lets two programs open it: their bytes then interleave
    and both sessions break. The first client locks the port; the second gets "robot busy"
    (exit 4 in the CLI) and the first keeps its SIPs."""
    from robocli.errors import DeviceError

    with PioneerSim("p3dx", time_scale=5.0) as sim:
        path = sim.serve_pty()
        with Pioneer.connect(path) as robot:
            first = robot.wait_for_sip().sip_count
            with pytest.raises(DeviceError, match="robot busy") as info:
                Pioneer.connect(path, timeout=1.0)
            assert info.value.exit_code == 4
            for _ in range(5):
                state = robot.wait_for_sip(timeout=10)
            assert state.sip_count > first
        with Pioneer.connect(path) as robot:  # the lock went with the first client
            robot.wait_for_sip()
