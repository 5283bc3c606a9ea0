"""The sensor hub as ``robocli serve`` runs it, callable from a program: a
:class:`~robocli.hub_server.HubServer` on TCP with its sources (simulated, a Pioneer, a Hokuyo, gpsd
or a recording replayed), and, on an open Zenoh session, its Zenoh front-end and ROS 2 topics.
:class:`HubService` wires them, says what it serves, and closes them all."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from robocli.errors import InvalidArgument
from robocli.hub_server.server import HubServer

if TYPE_CHECKING:
    import zenoh

__all__ = ["ZENOH_PUBLISH", "HubService"]

ZENOH_PUBLISH = "adc,imu,gps,battery,sysinfo"
"""What the Zenoh front-end publishes from the start, at each sensor's default settings."""


class HubService:
    """A hub server on ``bind:port`` (not listening until :meth:`start_tcp`) with the
    sources the arguments name: ``laser`` a Hokuyo's URL for the laser sensor, ``replay`` a
    recording played at ``speed`` (``loop``: again from the start at its end); the others
    as :class:`~robocli.hub_server.HubServer`'s. Close it (or use ``with``) to stop everything."""

    def __init__(self, bind: str = "127.0.0.1", port: int = 1500, *, sim: bool = False,
                 laser: str | None = None, replay: Path | None = None, speed: float = 1.0,
                 loop: bool = False, **options: Any) -> None:  # fmt: skip
        self.token = options.get("token")
        sources: dict[str, Any] = {}
        if replay is not None:
            from robocli.hub_server.sources.replay import replay_sources

            sources = replay_sources(replay, speed, loop)
        if laser:
            from robocli.hub_server.sources.hokuyo import HokuyoSource

            sources["laser"] = HokuyoSource(laser)
        self.sim, self.laser, self.replay = sim, laser, replay
        self.server = HubServer(bind, port, sim=sim, sources=sources, **options)
        self.frontend: Any = None
        self.ros: Any = None
        self._zenoh_at = ""
        self._domain = 0

    def start_tcp(self) -> None:
        """Listen for ros4mat clients on TCP."""
        self.server.start()

    def start_zenoh(self, session: zenoh.Session, name: str,
                    publish: dict[str, dict[str, Any] | None] | None = None,
                    ros2: dict[str, Any] | None = None, where: str = "") -> None:  # fmt: skip
        """Serve on ``session`` (closed with the service) as ``robocli/NAME/*``, publishing
        ``publish`` (:meth:`published`; default :data:`ZENOH_PUBLISH`) from the start;
        ``ros2``: also as ROS 2 topics, with :class:`~robocli.hub_server.frontends.ros2.HubTopics`'
        ``domain`` and ``namespace``. ``where``: the session's endpoint, as :meth:`served`
        names it."""
        from robocli.hub_server.frontends.zenoh import ZenohFrontend
        from robocli.zenoh.session import close_session

        self._zenoh_at = where
        try:
            srv = self.server
            self.frontend = ZenohFrontend(srv.hub, session, name, token=self.token,
                                          publish=self.published(ZENOH_PUBLISH)
                                          if publish is None else publish,
                                          serial=srv.serial).start()  # fmt: skip
        except BaseException:
            close_session(session)
            raise
        if ros2 is not None:
            from robocli.hub_server.frontends.ros2 import HubTopics

            self.ros = HubTopics(srv.hub, session, self.frontend.name, **ros2)
            self._domain = ros2.get("domain", 0)
            self.frontend.on_batch = self.ros.batch

    def published(self, text: str) -> dict[str, dict[str, Any] | None]:
        """``SENSOR[=RATE],...`` -> sensor -> its settings (None: defaults); sensors this hub
        does not have are left out of the default list, refused when named
        (:class:`InvalidArgument`)."""
        from robocli.devices.hub.over_zenoh import hub_name_of
        from robocli.devices.hub.subscription import subscribe_request

        out: dict[str, dict[str, Any] | None] = {}
        for item in filter(None, (part.strip() for part in text.split(","))):
            sensor, _, rate = item.partition("=")
            try:
                hub_sensor = hub_name_of(sensor.strip())
                params = subscribe_request(sensor.strip(), float(rate))["params"] if rate else None
            except (InvalidArgument, ValueError) as exc:
                raise InvalidArgument(f"{item!r}: {exc}") from None
            if hub_sensor in self.server.hub.channels:
                out[hub_sensor] = params
            elif text != ZENOH_PUBLISH:
                raise InvalidArgument(f"this hub has no {hub_sensor}")
        return out

    def notes(self, pioneer: str | None = None, gpsd: str | None = None) -> list[str]:
        """What replaces simulated sensors when real ones are given beside ``sim``."""
        if not self.sim:
            return []
        notes = []
        if pioneer:
            notes.append(f"adc and battery: from the Pioneer at {pioneer.strip()} (--pioneer "
                         "replaces the simulated ones)")  # fmt: skip
        if gpsd:
            notes.append(f"gps: from gpsd at {gpsd} (--gpsd replaces the simulated one)")
        if self.laser:
            notes.append(f"laser: from the Hokuyo at {self.laser.strip()} (--laser replaces "
                         "the simulated one)")  # fmt: skip
        return notes

    def served(self) -> str:
        """One line: what the hub serves and where."""
        srv = self.server
        where = [srv.url] if srv.started else []
        if self.frontend is not None:
            where.append(f"zenoh robocli/{self.frontend.name}/* ({self._zenoh_at})")
        if self.ros is not None:
            where.append(f"ROS 2 domain {self._domain}")
        what = f"hub replaying {self.replay}: " if self.replay is not None else "hub "
        served = [*srv.sensors, *(f"serial port {p}" for p in srv.serial_ports)]
        return f"{what}serving {', '.join(served)} on {' and '.join(where)}"

    def status_lines(self) -> list[str]:
        """One line per active sensor and per known client."""
        lines = []
        for name, s in self.server.sensors.items():
            if s["active"]:
                lines.append(f"sensor {name}: {s['rate']:g} Hz, {s['subscribers']} subscriber(s)")
        for c in self.server.clients:
            state = "connected" if c.connected else "detached"
            subs = ", ".join(f"{n}[{b}]" for n, b in c.subscriptions.items()) or "nothing"
            lines.append(f"client {c.id} {c.peer} {state}: {subs}")
        return lines

    def close(self) -> None:
        """Stop the Zenoh front-end, the ROS 2 topics, the session and the server."""
        if self.frontend is not None:
            from robocli.zenoh.session import close_session

            self.frontend.close()
            if self.ros is not None:
                self.ros.close()
            close_session(self.frontend.session)
        self.server.close()

    def __enter__(self) -> HubService:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
