"""The one contract every device client keeps (robocli.devices.base.Device), each against
its built-in simulator started by a ``sim://`` URL: connect, context manager, close twice,
listeners (a removed one gets nothing more), stats, and a typed error on a dead link."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import pytest

import robocli
from robocli.devices.base import Device, ListenerHandle
from robocli.errors import ConnectionLost
from tests.waiting import wait_for

DEADLINE_S = 20.0  # generous: the suite runs with the CPU oversubscribed


@dataclass
class Case:
    name: str
    connect: Callable[[], Any]
    traffic: Callable[[Any], object]  # something that makes frames flow (a request...)
    after_death: Callable[[Any], object]  # the device's ordinary next call (it may block)
    kill: Callable[[Any], object] = lambda device: device.simulator.close()


def _remote_pioneer() -> Any:
    """A RemotePioneer on zenoh/r1: a Pioneer on its simulator behind a bridge in this
    process, on a Zenoh server session listening on an ephemeral loopback port; the test
    kills the link by closing the bridge (its liveliness token goes)."""
    pytest.importorskip("zenoh", reason="needs robocli-robots[zenoh] (eclipse-zenoh)")
    from robocli.bridge.pioneer import PioneerBridge
    from robocli.zenoh.session import close_session, open_session

    endpoint = _free_endpoint()
    server = open_session(endpoint, "server")
    robot = robocli.Pioneer.connect("sim://?time_scale=4")
    bridge = PioneerBridge(robot, server, "r1")
    try:
        remote = robocli.RemotePioneer.connect("zenoh/r1", endpoint, holder="contract")
    except BaseException:
        bridge.close(), robot.close(), close_session(server)
        raise
    remote.behind = (bridge, robot, server)  # closed by the fixture (a test kills the bridge)
    return remote


def _zenoh_hub() -> Any:
    """A ZenohHub on the Zenoh front-end of a simulated hub in this process; the test kills
    the link by closing the front-end (its liveliness token goes)."""
    pytest.importorskip("zenoh", reason="needs robocli-robots[zenoh] (eclipse-zenoh)")
    from robocli.hub_server.frontends.zenoh import ZenohFrontend
    from robocli.zenoh.session import close_session, open_session

    endpoint = _free_endpoint()
    server = robocli.HubServer(port=0, sim=True).start()
    session = open_session(endpoint, "server")
    front = ZenohFrontend(server.hub, session, "lab", publish={"adc": {}}).start()
    try:
        hub = robocli.ZenohHub.connect("zenoh/lab", zenoh=endpoint)
    except BaseException:
        front.close(), close_session(session), server.close()
        raise
    hub.behind = (front, server, session)
    return hub


def _free_endpoint() -> str:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{s.getsockname()[1]}"


def _hub_traffic(hub: Any) -> object:
    return hub.pull("adc") if "adc" in hub._subscribed else hub.subscribe("adc", rate=50)


def _query_once_gone(hub: Any) -> object:
    """Over Zenoh the hub's leaving is told by its liveliness token, which may come after
    the unanswered query: once it came, a query raises ConnectionLost."""
    wait_for(lambda: not hub.alive, "the hub's liveliness token to go")
    return hub.info()


def _wait_for_batches(hub: Any) -> None:
    before = hub.stats.as_dict()["received"].get("adc", 0)
    wait_for(lambda: hub.stats.as_dict()["received"].get("adc", 0) > before, "a batch")


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
    Case("RemotePioneer", _remote_pioneer, lambda r: r.wait_for_state(DEADLINE_S),
         lambda r: r.wait_for_state(DEADLINE_S), lambda r: r.behind[0].close()),
    Case("ZenohHub", _zenoh_hub, lambda h: h.subscribe("adc") or _wait_for_batches(h),
         _query_once_gone, lambda h: h.behind[0].close()),
]  # fmt: skip


@pytest.fixture(params=CASES, ids=[c.name for c in CASES])
def case(request: pytest.FixtureRequest) -> Iterator[Case]:
    made: list[Any] = []
    param: Case = request.param
    yield Case(param.name, lambda: made.append(param.connect()) or made[-1], param.traffic,
               param.after_death, param.kill)  # fmt: skip
    for device in made:
        device.close()
        behind = getattr(device, "behind", ())
        for part in behind:
            if hasattr(part, "close"):
                part.close()
            else:
                from robocli.zenoh.session import close_session

                close_session(part)


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
        simulator = getattr(device, "simulator", None)
    assert not device.alive
    with pytest.raises(ConnectionLost):
        device.check()
    assert device.close() is None  # a second close: nothing, no error
    assert device.close(stop=True) is None
    if simulator is not None:  # a sim:// device: its simulator went too
        assert all(_refused(url) for url in simulator.urls.values())


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
        wait_for(lambda: any(t > removed_at for _, _, t in kept[before:]), "frames after removal")
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
        case.kill(device)  # the simulator (or the bridge) dies under the client
        deadline = time.monotonic() + DEADLINE_S
        with pytest.raises(ConnectionLost):  # a call that needs the link, not a hang
            while True:  # (what was already on its way, a SIP or a sample, may still come)
                case.after_death(device)
                assert time.monotonic() < deadline, "the dead link was never reported"
        assert not device.alive
        with pytest.raises(ConnectionLost):
            device.check()
