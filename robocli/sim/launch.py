"""The simulators as ``robocli sim abb|pioneer`` start them, from the same options: for a
script that serves one on a fixed port, the way the CLI does."""

from __future__ import annotations

from functools import partial
from typing import TYPE_CHECKING, Any

from robocli.errors import InvalidArgument

if TYPE_CHECKING:
    from robocli.sim.abb.server import AbbSim
    from robocli.sim.pioneer.server import PioneerSim
    from robocli.sim.replay import PacketSource
    from robocli.sim.world import World

__all__ = ["abb_controller", "pioneers"]


def abb_controller(robot: str = "irb120", *, profile: str = "abb", state_ms: float | None = None,
                   byte_order: str = "little", real_size: int = 4, time_scale: float = 1.0,
                   paper: bool = False, feedback: bool = False, latency_ms: float = 0.0,
                   jitter_ms: float = 0.0, noise_rad: float = 0.0, period_jitter_ms: float = 0.0,
                   lag_ms: float = 0.0) -> AbbSim:  # fmt: skip
    """A simulated ABB controller, not serving yet (``serve_tcp`` it): ``profile`` ``abb``
    (RAPID servers) or ``generic`` (streaming), a state every ``state_ms`` (default: 100
    as ABB's stock code, 20 with ``paper``), the exact model unless ``paper`` (the paper's
    controller) or any of the delays, jitters and noise is given."""
    from robocli.sim.abb.server import PROFILES, AbbSim, ControllerModel

    if profile not in PROFILES:
        raise InvalidArgument(f"--profile is one of {', '.join(PROFILES)}, not {profile!r}")
    delays = (latency_ms, jitter_ms, noise_rad, period_jitter_ms, lag_ms)
    model = ControllerModel.paper() if paper else ControllerModel(*delays)
    return AbbSim(robot, profile=profile, state_ms=state_ms or (20.0 if paper else 100.0),
                  byteorder=">" if byte_order == "big" else "<", real=8 if real_size == 8 else 4,
                  time_scale=time_scale, model=model, feedback=feedback)  # fmt: skip


def pioneers(n: int = 1, *, host: str = "127.0.0.1", port: int = 8101, pty: bool = False,
             world: World | None = None, laser: bool = True,
             georef: tuple[float, float, float] | None = None, replay: PacketSource | None = None,
             speed: float = 1.0, loop: bool = False,
             **options: Any) -> list[PioneerSim]:  # fmt: skip
    """``n`` simulated Pioneers serving on ``port``, ``port + 1``... of ``host`` (or each on
    a pseudo-terminal with ``pty``), in ``world``, with a simulated SICK laser unless
    ``laser`` is false, SIMSTAT's GPS fix from ``georef`` (lat, lon in deg, alt in m); or
    each replaying ``replay`` (a :class:`~robocli.sim.replay.PacketSource`, such as
    :class:`~robocli.io.record.replay.RecordedPackets` of a recording) at ``speed``
    (``loop``: again and again). ``options``:
    :class:`~robocli.sim.pioneer.server.PioneerSim`'s (``subtype``, ``sip_ms``, ``time_scale``)."""
    from robocli.sim.pioneer.server import serve_many

    options |= {"georef": georef} | ({} if laser else {"laser": None})
    if replay is not None:
        from robocli.sim.pioneer.replay import PioneerReplay

        options["factory"] = partial(PioneerReplay, replay, speed=speed, loop=loop)
    return serve_many(n, host=host, port=port, pty=pty, world=world, **options)
