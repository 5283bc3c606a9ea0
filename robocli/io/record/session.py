"""A recording of several devices, wired and run: what ``robocli record`` does, callable from
a notebook. :class:`RecordingSession` connects each source (each recorded from its first
byte), runs until a duration or count (raising the error of a link that was lost) and says
how far it got; the devices close with the session, before the recording is closed."""

from __future__ import annotations

import contextlib
import math
import os
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from robocli.errors import InvalidArgument

if TYPE_CHECKING:
    from robocli.devices.hub.client import Hub
    from robocli.io.record.recorder import Recorder

__all__ = ["HUB_DEFAULTS", "Progress", "RecordingSession", "hub_sensors"]

#: Sample rates (Hz) and settings a hub sensor is subscribed with unless ``NAME:RATE``.
HUB_DEFAULTS: dict[str, dict[str, Any]] = {
    "imu": {"rate": 200}, "adc": {"rate": 1000}, "laser": {"rate": 40},
    "camera": {"rate": 30, "resolution": "320x240"}, "gps": {"rate": 5},
    "battery": {"rate": 10}, "sysinfo": {"rate": 10},
    "depth": {"rate": 10, "resolution": "320x240"},
    "stereo": {"rate": 15, "resolution": "320x240"},
}  # fmt: skip


def hub_sensors(text: str) -> list[tuple[str, dict[str, Any]]]:
    """``imu,adc:500`` -> [("imu", {rate 200}), ("adc", {rate 500})]; an unknown sensor, a
    rate outside 1..65535 Hz or no sensor at all raise :class:`InvalidArgument`."""
    out = []
    for item in filter(None, (s.strip() for s in text.split(","))):
        name, _, rate = item.partition(":")
        name = name.lower()
        if name not in HUB_DEFAULTS:
            raise InvalidArgument(f"{name!r} is not a hub sensor; choose from "
                                  f"{', '.join(HUB_DEFAULTS)}")  # fmt: skip
        args = dict(HUB_DEFAULTS[name])
        if rate:
            if not rate.isdigit() or not 1 <= int(rate) <= 65535:
                raise InvalidArgument(f"{item!r}: the rate is 1..65535 Hz")
            args["rate"] = int(rate)
        out.append((name, args))
    if not out:
        raise InvalidArgument("name at least one sensor")
    return out


@dataclass(frozen=True)
class Progress:
    """How far a recording got."""

    messages: int  #: messages added so far
    size: int  #: bytes of the file so far
    seconds: float  #: since the recording began

    @property
    def rate(self) -> float:
        """Messages a second."""
        return self.messages / max(self.seconds, 1e-9)


class RecordingSession:
    """Sources connected on ``stack`` (closed with it) and added to ``rec``: call the
    ``add_*`` methods, then ``rec.begin()`` and :meth:`run`. :attr:`devices` maps each
    source's name in the recording to its device."""

    def __init__(self, rec: Recorder, stack: contextlib.ExitStack) -> None:
        self.rec, self.stack = rec, stack
        self.devices: dict[str, Any] = {}
        self.start = time.monotonic()
        self._hub: tuple[Hub, list[str]] | None = None

    def add_pioneer(self, url: str, timeout: float = 5.0, sim_laser: bool = True) -> str:
        """A Pioneer (a simulator's own laser started unless ``sim_laser`` is false)."""
        from robocli.devices.pioneer import Pioneer

        listener = self.rec.listener("pioneer", "arcos", url=url)
        robot = self.stack.enter_context(Pioneer.connect(url, listeners=[listener],
                                                         timeout=timeout))  # fmt: skip
        name = self._added(robot, listener.name)
        if sim_laser and robot.sim is not None:
            robot.sim.start_laser()
        return name

    def add_arm(self, address: tuple[str, int, int], *, byte_order: str = "little",
                real_size: int = 4, robot: str = "irb120",
                timeout: float = 5.0) -> str:  # fmt: skip
        """An arm's state port at ``(host, motion port, state port)``."""
        from robocli.devices.arm import Arm
        from robocli.io.record.arm import arm_links

        name, links = arm_links(self.rec, "arm", byte_order=byte_order, real_size=real_size,
                                ports="state")  # fmt: skip
        arm = self.stack.enter_context(Arm.connect(
            *address, motion=False, byte_order=byte_order, real_size=real_size, robot=robot,
            timeout=timeout, stop_on_failure=False,
            listeners={"state": [links["state"]]}))  # fmt: skip
        return self._added(arm, name)

    def add_laser(self, url: str, timeout: float = 5.0) -> str:
        """A Hokuyo streaming (closing sends QT, recorded), mounted on the first Pioneer as
        its robot model says (when there is one)."""
        from robocli.devices.laser import Laser

        first = next((n for n in self.devices if n.startswith("pioneer")), None)
        on = {} if first is None else {"parent": f"{first}/base_link",
                                       "mount": self.devices[first].params.laser_mount}  # fmt: skip
        listener = self.rec.listener("laser", "scip2", url=url)
        laser = self.stack.enter_context(Laser.connect(url, timeout=max(timeout, 2.0),
                                                       listeners=[listener]))  # fmt: skip
        name = self._added(laser, listener.name, **on)
        laser.start()
        return name

    def add_create(self, url: str, timeout: float = 5.0) -> str:
        """An iRobot Create 2 recorded from its first byte; ``sim``: a simulated one on an
        ephemeral loopback port (closed with the stack)."""
        from robocli.devices.create import Create

        if url == "sim":
            from robocli.sim.create import CreateSim

            url = self.stack.enter_context(CreateSim()).serve_tcp("127.0.0.1", 0)
        listener = self.rec.listener("create", "create-oi", url=url)
        robot = self.stack.enter_context(Create.connect(url, timeout=timeout,
                                                        listeners=[listener]))  # fmt: skip
        return self._added(robot, listener.name)

    def add_hub(self, connect: Callable[[Iterable[Any]], Hub], url: str,
                sensors: list[tuple[str, dict[str, Any]]]) -> str:  # fmt: skip
        """A hub at ``url``, opened by ``connect(listeners)``, subscribed to ``sensors``
        (from :func:`hub_sensors`) and pulled by :meth:`run`."""
        names = [n for n, _ in sensors]
        listener = self.rec.listener("hub", "ros4mat", url=url, sensors=",".join(names))
        client = self.stack.enter_context(connect([listener]))
        self.rec.add(client, listener.name, sensors=names)
        for name, args in sensors:
            client.subscribe(name, **args)
        self.devices["hub"] = client
        self._hub = (client, names)
        return "hub"

    def _added(self, device: Any, name: str, **options: Any) -> str:
        name = self.rec.add(device, name, **options)
        self.devices[name] = device
        return name

    def check(self) -> None:
        """Raise the error of a full disk, or of a device whose link was lost."""
        self.rec.check()  # the disk is full: stop now, what was written stays readable
        for name, device in self.devices.items():
            if name.startswith("pioneer") and not device.alive:
                device.wait_for_sip(0)  # raises why the session ended
            elif name.startswith("arm"):
                device.check()
            elif name.startswith(("laser", "create")):
                device.session.check()

    def progress(self) -> Progress:
        """Messages, bytes written and seconds so far."""
        try:
            size = os.stat(self.rec.path).st_size
        except OSError:
            size = 0
        return Progress(self.rec.stats.added, size, time.monotonic() - self.start)

    def run(self, duration: float | None = None, count: int | None = None,
            poll_hz: float = 20, on_tick: Callable[[], None] | None = None) -> None:  # fmt: skip
        """Record until ``duration`` s (from now) or ``count`` messages, pulling the hub's
        sensors ``poll_hz`` times a second; ``on_tick`` is called every turn. Raises what
        :meth:`check` raises."""
        self.start = time.monotonic()
        end = self.start + duration if duration is not None else math.inf

        def done() -> bool:
            self.check()
            if on_tick is not None:
                on_tick()
            return time.monotonic() >= end or (count is not None and
                                               self.rec.stats.added >= count)  # fmt: skip

        if self._hub is not None:
            from robocli.io.record.hub import pull_hub

            pull_hub(self._hub[0], self._hub[1], poll_hz, done)
            return
        while not done():
            time.sleep(0.05)
