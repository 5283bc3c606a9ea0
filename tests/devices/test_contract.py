"""The one contract every device client keeps (robocli.devices.base.Device), each against
its built-in simulator started by a ``sim://`` URL: connect, context manager, close twice,
listeners (a removed one gets nothing more), stats, and a typed error on a dead link."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import pytest

import robocli
from robocli.devices.base import Device, ListenerHandle
from robocli.errors import ConnectionLost

DEADLINE_S = 20.0  # generous: the suite runs with the CPU oversubscribed


@dataclass
class Case:
    name: str
    connect: Callable[[], Any]
    traffic: Callable[[Any], object]  # something that makes frames flow (a request...)
    after_death: Callable[[Any], object]  # the device's ordinary next call (it may block)


def _hub_traffic(hub: Any) -> object:
    return hub.pull("adc") if "adc" in hub._subscribed else hub.subscribe("adc", rate=50)


CASES = [
    Case("Pioneer", lambda: robocli.Pioneer.connect("sim://p3dx?time_scale=4"),
         lambda r: r.wait_for_sip(timeout=DEADLINE_S),
         lambda r: r.wait_for_sip(timeout=DEADLINE_S)),
    Case("Arm", lambda: robocli.Arm.connect("sim://"),
         lambda a: a.wait_for_state(DEADLINE_S), lambda a: a.wait_for_state(DEADLINE_S)),
    Case("Hub", lambda: robocli.Hub.connect("sim://"), _hub_traffic,
         lambda h: h.pull("adc")),
    Case("Laser", lambda: robocli.Laser.connect("sim://"),
         lambda laser: laser.scan(), lambda laser: laser.scan()),
]  # fmt: skip


@pytest.fixture(params=CASES, ids=[c.name for c in CASES])
def case(request: pytest.FixtureRequest) -> Case:
    return request.param  # type: ignore[no-any-return]


def _wait(condition: Callable[[], bool], what: str) -> None:
    deadline = time.monotonic() + DEADLINE_S
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.01)


def _refused(url: str) -> bool:
    host, port = url.removeprefix("tcp://").rsplit(":", 1)
    try:
        socket.create_connection((host, int(port)), timeout=2.0).close()
    except OSError:
        return True
    return False


def test_connect_context_manager_and_close_twice(case: Case) -> None:
    with case.connect() as device:
        assert isinstance(device, Device)
        assert device.alive
        device.check()
        simulator = device.simulator
        assert simulator is not None
    assert not device.alive
    with pytest.raises(ConnectionLost):
        device.check()
    assert device.close() is None  # a second close: nothing, no error
    assert device.close(stop=True) is None
    assert all(_refused(url) for url in simulator.urls.values())  # its simulator went too


def test_listeners_get_frames_and_a_removed_one_none(case: Case) -> None:
    with case.connect() as device:
        kept: list[tuple[str, bytes, float]] = []
        removed: list[tuple[str, bytes, float]] = []
        got = threading.Event()

        def listen(direction: str, frame: bytes, t: float) -> None:
            removed.append((direction, frame, t))
            got.set()

        device.add_listener(lambda d, f, t: kept.append((d, f, t)))
        handle = device.add_listener(listen)
        assert isinstance(handle, ListenerHandle)
        case.traffic(device)
        assert got.wait(DEADLINE_S)
        assert {d for d, _, _ in removed} <= {"tx", "rx"}
        handle.remove()
        handle.remove()  # idempotent
        removed_at = time.monotonic()
        before = len(kept)
        case.traffic(device)
        _wait(lambda: any(t > removed_at for _, _, t in kept[before:]), "frames after removal")
        assert all(t <= removed_at for _, _, t in removed)


def test_stats(case: Case) -> None:
    with case.connect() as device:
        case.traffic(device)
        stats = device.stats.as_dict()
        assert isinstance(stats, dict) and stats
        flat = str(stats)
        assert "received" in flat and "listener_errors" in flat


def test_a_dead_link_is_a_typed_error(case: Case) -> None:
    with case.connect() as device:
        case.traffic(device)
        device.simulator.close()  # the simulator dies under the client
        started = time.monotonic()
        with pytest.raises(ConnectionLost):  # the next call that needs the link, not a hang
            case.after_death(device)
        assert time.monotonic() - started < DEADLINE_S
        assert not device.alive
        with pytest.raises(ConnectionLost):
            device.check()
