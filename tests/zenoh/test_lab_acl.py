"""A lab behind a router with access control, run from ``examples/lab-router.json5`` (the
shipped example, which is what ``robocli router --users FILE --acl`` generates): the hub
``hub1``, the bridge ``r1`` and the students ``alice`` and ``bob`` connect as Zenoh clients
with their own credentials, on loopback, multicast scouting off. Bob, with valid lab
credentials, cannot drive alice's robot, release it for her, keep her token alive once
she is gone, or put sensor batches on the hub's keys; alice and the hub still work."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from robocli.bridge import RemotePioneer
from robocli.devices.hub.over_zenoh import ZenohHub
from robocli.errors import DeviceError, TimeoutError
from robocli.sim.pioneer.server import PioneerSim
from robocli.zenoh import open_session
from robocli.zenoh.acl import lab_access_control
from robocli.zenoh.batch import encode_head
from tests.bridge.bridge_helpers import DEADLINE, Events, bridge_process, read_line
from tests.paths import EXAMPLES
from tests.peers import free_endpoint
from tests.waiting import wait_for
from tests.zenoh.test_cli_zenoh import robocli, running


@dataclass
class Lab:
    """The router's endpoint and each user's client configuration."""

    endpoint: str
    configs: dict[str, Path]

    def session(self, user: str) -> Any:
        return open_session(str(self.configs[user]), "client")


def _passwords() -> dict[str, str]:
    lines = (EXAMPLES / "lab-users.txt").read_text().split()
    return dict(line.split(":", 1) for line in lines)  # type: ignore[misc]


@pytest.fixture
def lab(tmp_path: Path) -> Iterator[Lab]:
    """The example router (from its own folder, as the README runs it) on a free port."""
    for name in ("lab-router.json5", "lab-users.txt"):
        shutil.copy(EXAMPLES / name, tmp_path / name)
    endpoint = free_endpoint()
    configs = {}
    for user, password in _passwords().items():
        cfg = {"mode": "client", "connect": {"endpoints": [endpoint]},
               "scouting": {"multicast": {"enabled": False}},
               "transport": {"auth": {"usrpwd": {"user": user, "password": password}}}}  # fmt: skip
        configs[user] = tmp_path / f"{user}.json5"
        configs[user].write_text(json.dumps(cfg))
    with running("router", "--config", str(tmp_path / "lab-router.json5"), "--listen", endpoint,
                 ready="zenoh router", cwd=tmp_path):  # fmt: skip
        yield Lab(endpoint, configs)


def test_the_example_is_what_robocli_router_acl_generates() -> None:
    z = pytest.importorskip("zenoh")
    example = z.Config.from_file(str(EXAMPLES / "lab-router.json5"))
    generated = z.Config()  # through Zenoh's parser too: it adds its defaults to both
    generated.insert_json5("access_control", json.dumps(lab_access_control(_passwords())))
    assert example.get_json("access_control") == generated.get_json("access_control")
    assert json.loads(example.get_json("access_control/default_permission")) == "deny"
    assert json.loads(example.get_json("scouting/multicast/enabled")) is False


def _stopped(simulator: PioneerSim) -> bool:
    state = simulator.snapshot()
    return state.trans_vel_set == 0 and state.rot_vel_set == 0


def test_another_user_cannot_drive_the_robot_or_release_it_for_its_holder(lab: Lab) -> None:
    with PioneerSim() as simulator:
        port = simulator.serve_tcp("127.0.0.1", 0)
        args = ["pioneer", port, "--zenoh", str(lab.configs["r1"]), "--name", "r1"]
        with bridge_process(args):
            alice = RemotePioneer.connect("r1", str(lab.configs["alice"]))
            bob = lab.session("bob")
            try:
                assert alice.holder == "alice"  # the configuration's user
                events = Events(bob, "robocli/r1/@control/event")
                alice.set_velocity(0.3)
                wait_for(lambda: simulator.snapshot().trans_vel_set > 0.1, "alice drives")
                alice.stop()
                wait_for(lambda: _stopped(simulator), "alice's stop")
                seen: list[bytes] = []
                for key in ("robocli/r1/state", "robocli/bob/probe"):
                    alice._session.declare_subscriber(
                        key, lambda s: seen.append(s.payload.to_bytes()))  # fmt: skip
                # bob, in alice's name or through wildcards: set-points, states, a release
                for key in ("robocli/r1/@control/alice/velocity", "robocli/*/@control/*/velocity",
                            "robocli/r1/state", "robocli/*/state", "robocli/**"):  # fmt: skip
                    bob.put(key, b'{"v":0.5,"w":0.5}')

                def probed() -> bool:  # after bob's forgeries, on the same links
                    bob.put("robocli/bob/probe", b"probe")
                    return b"probe" in seen

                wait_for(probed, "bob's probe reaches alice")
                assert b'{"v":0.5,"w":0.5}' not in seen  # no state of bob's reached alice
                release = bob.get("robocli/r1/@control/alice/request",
                                  payload=b'{"op":"release"}', timeout=1.0)  # fmt: skip
                assert [r for r in release if r.ok is not None] == []  # the router dropped it
                # and as himself: refused while alice holds it; his commands ignored
                reply = _ask(bob, "robocli/r1/@control/bob/request", {"op": "acquire"})
                assert reply["granted"] is False and reply["holder"] == "alice"
                bob.put("robocli/r1/@control/bob/velocity", b'{"v":0.5}')
                wait_for(lambda: events.find(event="ignored", holder="bob"), "bob ignored")
                assert _stopped(simulator)  # none of bob's set-points reached the robot
                assert _ask(bob, "robocli/r1/@control", {"op": "status"}) == {"holder": "alice"}
            finally:
                alice.close()
                bob.close()


_HOLD = """
import sys, time
from robocli.bridge import RemotePioneer
robot = RemotePioneer.connect("r1", sys.argv[1])
robot.acquire()
print("held", flush=True)
time.sleep(600)
"""


def test_a_forged_token_does_not_keep_a_killed_holder_holding(lab: Lab) -> None:
    with PioneerSim() as simulator:
        port = simulator.serve_tcp("127.0.0.1", 0)
        args = ["pioneer", port, "--zenoh", str(lab.configs["r1"]), "--name", "r1"]
        with bridge_process(args):
            bob = lab.session("bob")
            holder = subprocess.Popen([sys.executable, "-c", _HOLD, str(lab.configs["alice"])],
                                      stdout=subprocess.PIPE, text=True)  # fmt: skip
            try:
                assert read_line(holder, DEADLINE).strip() == "held"
                events = Events(bob, "robocli/r1/@control/event")
                forged = bob.liveliness().declare_token("robocli/r1/@control/alice/alive")
                reply = _ask(bob, "robocli/r1/@control/bob/request", {"op": "acquire"})
                assert reply["granted"] is False and reply["holder"] == "alice"
                holder.kill()  # no goodbye: only its session's end tells
                gone = wait_for(lambda: events.find(event="released", holder="alice"),
                                "alice's robot released when she is killed")  # fmt: skip
                assert "left" in gone["reason"]
                reply = _ask(bob, "robocli/r1/@control/bob/request", {"op": "acquire"})
                assert reply["granted"] is True and reply["holder"] == "bob"
                forged.undeclare()
            finally:
                holder.kill()
                holder.wait(DEADLINE)
                if holder.stdout is not None:
                    holder.stdout.close()
                bob.close()


def _ask(session: Any, key: str, request: dict[str, Any]) -> dict[str, Any]:
    for reply in session.get(key, payload=json.dumps(request).encode(), timeout=DEADLINE):
        sample = reply.ok if reply.ok is not None else reply.err
        result: dict[str, Any] = json.loads(sample.payload.to_bytes())
        return result
    raise AssertionError(f"no reply on {key}")


def test_another_user_cannot_put_sensor_batches_on_the_hubs_keys(lab: Lab) -> None:
    # no --name: the hub is named hub1, its configuration's user
    hub_args = ["serve", "--sim", "--no-tcp", "--zenoh", str(lab.configs["hub1"]),
                "--publish", "adc=100"]  # fmt: skip
    with running(*hub_args, ready="hub serving"):
        with ZenohHub.connect("hub1", zenoh=str(lab.configs["alice"]), history=False) as hub:
            hub.subscribe("adc")
            wait_for(lambda: len(hub.read("adc").t) > 0, "alice reads the hub's samples")
            bob, probe = lab.session("bob"), []
            sub = hub.zsession.declare_subscriber("robocli/bob/probe", probe.append)
            try:
                record = np.zeros(1, [("v", "<f4", 8), ("t", "<f8")])
                record["v"], record["t"] = 1234.5, 1.0
                body = record.tobytes()
                for first in (0, 1 << 40):
                    head = encode_head(0x20, first, 1, len(body), 1.0)
                    bob.put("robocli/hub1/adc", head + body)

                def probed() -> bool:  # bob's own key passes; until alice's subscriber is known
                    bob.put("robocli/bob/probe", b"after the forgeries")
                    return bool(probe)

                wait_for(probed, "bob's own put, after his forged ones")
                readings = []

                def more() -> bool:
                    readings.append(hub.read("adc"))
                    return len(readings[-1].t) > 0

                wait_for(more, "the hub's samples after bob's forgeries")
                assert not any(np.isclose(r.data, 1234.5).any() for r in readings)
                assert hub.rejected.get("adc", 0) == 0  # nothing forged even reached alice
                assert sum(r.lost for r in readings) < 1000  # no gap of 2^40 either
            finally:
                sub.undeclare()
                bob.close()
        out = robocli("list", "--zenoh", str(lab.configs["bob"]), "--json")
        assert {"name": "hub1", "kind": "hub"} in json.loads(out.stdout)


def test_a_holder_name_that_is_not_its_user_is_dropped_by_the_router(lab: Lab) -> None:
    with PioneerSim() as simulator:
        port = simulator.serve_tcp("127.0.0.1", 0)
        args = ["pioneer", port, "--zenoh", str(lab.configs["r1"]), "--name", "r1"]
        with bridge_process(args):
            with RemotePioneer.connect("r1", str(lab.configs["bob"]), holder="alice") as fake:
                fake.timeout = 1.0  # what the router drops is never answered: wait 1 s only
                with pytest.raises(TimeoutError, match="only the user alice may ask as alice"):
                    fake.set_velocity(0.2)
                assert not fake.held
            with RemotePioneer.connect("r1", str(lab.configs["bob"])) as bob:
                bob.set_velocity(0.2)
                wait_for(lambda: simulator.snapshot().trans_vel_set > 0.1, "bob drives as bob")
                with pytest.raises(DeviceError):
                    with RemotePioneer.connect("r1", str(lab.configs["alice"])) as alice:
                        alice.set_velocity(0.1)


def test_router_acl_from_a_users_file_and_its_usage_errors(tmp_path: Path) -> None:
    users = tmp_path / "users.txt"
    users.write_text("alice:pa\n")
    alone = robocli("router", "--listen", free_endpoint(), "--acl")
    assert alone.returncode == 2 and "--acl needs --users" in alone.stderr
    bad = tmp_path / "bad.txt"
    bad.write_text("alice:pa\n@admin:px\n")
    refused = robocli("router", "--listen", free_endpoint(), "--users", str(bad), "--acl")
    assert refused.returncode == 2 and "'@admin'" in refused.stderr, refused.stderr
    endpoint = free_endpoint()
    cfg = tmp_path / "alice.json5"
    cfg.write_text(json.dumps({"mode": "client", "connect": {"endpoints": [endpoint]},
                               "transport": {"auth": {"usrpwd": {"user": "alice",
                                                                 "password": "pa"}}}}))  # fmt: skip
    with running("router", "--listen", endpoint, "--users", str(users), "--acl",
                 ready="zenoh router"):  # fmt: skip
        listed = robocli("list", "--zenoh", str(cfg), "--json")
        assert listed.returncode == 0 and json.loads(listed.stdout) == [], listed.stderr
