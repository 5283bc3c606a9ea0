"""The simulator's per-command work: decoded commands are reused, within a bound."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from robocli.protocols.arcos import Command, PacketType
from robocli.sim.pioneer.server import PioneerSim

if TYPE_CHECKING:
    from tests.sim.conftest import RawClient

MakeSim = Callable[..., PioneerSim]
Connect = Callable[[PioneerSim], "RawClient"]


def test_many_distinct_commands_are_all_obeyed_and_the_decode_cache_stays_bounded(
    make_sim: MakeSim, connect: Connect
) -> None:
    sim = make_sim()
    client = connect(sim)
    client.open_session(enable=True)
    n = 700  # distinct payloads, well past the cache's bound
    for mm_s in range(1, n + 1):
        client.send(Command.VEL, mm_s)
    client.send(Command.VEL, 123)  # one seen before (its decoded form may be reused)
    client.send(Command.CONFIG, 1)
    config = client.expect(PacketType.CONFIG)  # the link has handled every command before it
    assert config[0] == PacketType.CONFIG
    assert sim.snapshot().commands["VEL"] == n + 1
    # the last VEL wins (decoded from the cache); the model takes it at its next tick
    sim.wait_until(lambda s: abs(s.trans_vel_set - 0.123) < 1e-9, 30)
    assert len(sim._ctl._decoded) <= 256  # bounded whatever the client sends
