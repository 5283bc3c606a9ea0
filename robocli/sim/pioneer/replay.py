"""A Pioneer that plays a recording back (``robocli sim pioneer --replay FILE.mcap``).

Any ARCOS client connects to it as to the simulator: the handshake is answered as the
simulator answers it, under the recorded robot's name and subtype (from the recording's
SYNC2 reply, when it was recorded from the handshake on), and CONFIG requests get the
recorded CONFIG packet (else the simulator's for that subtype). Once the client has OPENed
the session, the robot's recorded stream (every packet it sent after the handshake: SIPs,
laser, SIMSTAT, IO, encoder... but CONFIG and the handshake replies) is sent again, byte for
byte, on its recorded spacing (the recording's receive times; ``speed`` times as fast), as
far as the client asked for it, as the live simulator sends it: the SIPs always; the laser
packets of the format the client enabled (0x61 after an enable of 2, 0x60 after 1) from the
first whole scan after its request to its "off"; SIMSTAT (0x62) after SIM_STAT 1 (once) or
2; encoder, IO and battery packets after their requests (1: once, 2: every cycle). A client
that asked for nothing gets SIPs only (ARIA logs every packet no handler wanted). A client
therefore decodes the recorded poses, sonar and laser scans. Commands are taken
(the watchdog is fed, CLOSE ends the session) but do not move anything; each new session
starts the recording over. With ``loop`` it starts over at its end as well.
"""

from __future__ import annotations

from typing import Any

from robocli.protocols.arcos import Command, PacketType
from robocli.serving.ticker import Ticker
from robocli.sim.laser import LMS200
from robocli.sim.pioneer.server import PioneerSim
from robocli.sim.pioneer.session import ArcosController, ArcosSession
from robocli.sim.pioneer.simext import LASER_EXTENDED, LASER_OFF, LASER_PLAIN
from robocli.sim.replay import FrameSchedule, PacketSource

__all__ = ["PioneerReplay", "ReplayController"]

TICK_S = 0.005  #: how often the stream is checked for frames due (wall s)
#: Replies to requests and handshake packets: answered, never replayed.
_NOT_STREAMED = frozenset({PacketType.SYNC0, PacketType.SYNC1, PacketType.SYNC2,
                           PacketType.CONFIG, PacketType.SIM_INFO})  # fmt: skip
#: Packets sent only on a request of the link's (``ArcosSession.requests``), by type.
_REQUESTED: dict[int, str] = {PacketType.ENCODER: "encoder", PacketType.IO: "io",
                              PacketType.BATTERY: "battery"}  # fmt: skip
#: The laser format each packet type belongs to.
_LASER: dict[int, int] = {PacketType.SIM_LASER_A: LASER_PLAIN,
                          PacketType.SIM_LASER: LASER_EXTENDED}  # fmt: skip


class ReplayController(ArcosController):
    """The simulator's ARCOS firmware with the robot's packets taken from a recording."""

    def __init__(self, model: Any, *, schedule: FrameSchedule, config_frame: bytes | None,
                 **options: Any) -> None:  # fmt: skip
        super().__init__(model, **options)
        self.schedule, self.config_frame = schedule, config_frame
        self._playing: ArcosSession | None = None
        self._laser_scan = False  # the laser's packets go out: a whole scan began since enabled
        #: recorded packets not sent, the client not having asked for them
        self.withheld = 0

    def tick(self, now: float) -> tuple[ArcosSession | None, bytes]:
        with self.lock:
            holder = self.holder
            if holder is None:
                return None, b""
            if holder is not self._playing:
                self._playing = holder
                self.schedule.restart(now)
            self._housekeeping(now)
            frames = [f for f in self.schedule.due(now) if self._asked(holder, f, now)]
        return holder, b"".join(frames)

    def _asked(self, link: ArcosSession, f: bytes, now: float) -> bool:
        """Whether the client asked for the recorded packet ``f`` (a whole frame) now; a
        SIP also applies what the client's commands deferred to it (SIM_STAT 2)."""
        ptype, ext = f[3], self.ext
        if ptype & 0xF0 == 0x30:
            ext.before_sip(self.sips, now)
            self.sips += 1
            return True
        mode = _LASER.get(ptype)
        if mode is not None:
            if ext.laser_mode != mode:
                self._laser_scan = False
            elif not self._laser_scan:  # from the first packet of a scan on
                first = f[6:8] if ptype == PacketType.SIM_LASER else f[12:14]
                self._laser_scan = first == b"\0\0"
            return self._count(self._laser_scan)
        if ptype == PacketType.SIM_STAT:
            once, ext.simstat_once = ext.simstat_once, False
            return self._count(once or ext.simstat_mode == 2)
        kind = _REQUESTED.get(ptype)
        if kind is not None:
            asked = link.requests[kind]
            if asked == 1:
                link.requests[kind] = 0
            return self._count(asked != 0)
        return True

    def _count(self, asked: bool) -> bool:
        if not asked:
            self.withheld += 1
        return asked

    def handle(self, link: ArcosSession, payload: bytes, now: float) -> bytes | None:
        reply = super().handle(link, payload, now)
        if self.ext.laser_mode == LASER_OFF:
            self._laser_scan = False
        if self.holder is None and self._playing is not None:
            self._playing = None  # the session ended: the next one starts over
            self.schedule.stop()
        if reply and self.config_frame is not None and payload[:1] == bytes([Command.CONFIG]):
            return self.config_frame
        return reply


class PioneerReplay(PioneerSim):
    """:class:`~robocli.sim.pioneer.server.PioneerSim`'s server (TCP or pty, one client at
    a time) playing back the Pioneer recorded in ``source`` (see the module docstring; a
    recording's is ``RecordedPackets(path)`` of :mod:`robocli.io.record.replay`). Keyword
    arguments go to :class:`PioneerSim` (``watchdog_s``...)."""

    def __init__(self, source: PacketSource, *, speed: float = 1.0, loop: bool = False,
                 **options: Any) -> None:  # fmt: skip
        from robocli.robots.pioneer import ROBOT_PARAMS

        frames = source.frames("arcos", "rx")
        name, subtype = _identity(frames)
        stream = [(t, f) for t, f in frames if f[3] not in _NOT_STREAMED]
        schedule = FrameSchedule(stream, speed, loop)
        given = options.pop("subtype", "p3dx")
        model_subtype = subtype if subtype in ROBOT_PARAMS else given
        super().__init__(model_subtype, name=name or "robocli-replay", **options)
        old = self._ctl
        self._ctl = self._replay = ReplayController(
            old.model, schedule=schedule,
            config_frame=next((f for _, f in frames if f[3] == PacketType.CONFIG), None),
            name=old.name, subtype=subtype or model_subtype, sip_ms=old.sip_ms,
            period=old._period, watchdog_s=old.watchdog_s, laser=options.get("laser", LMS200),
            georef=options.get("georef"), seed=options.get("seed", 0),
            reflectors=options.get("reflectors", ()),
            state_of_charge=options.get("state_of_charge", False),
        )  # fmt: skip
        self._ticker = Ticker(TICK_S, self._tick, "pioneer-replay-ticker")
        self.path, self.schedule = source.name, schedule

    @property
    def withheld(self) -> int:
        """Recorded packets not sent, the client not having asked for them."""
        return self._replay.withheld

    def _tick(self, now: float) -> None:
        session, data = self._ctl.tick(now)
        if session is not None and data:
            session.link.send(data)


def _identity(frames: list[tuple[float, bytes]]) -> tuple[str, str]:
    """(name, subtype) from the recorded SYNC2 reply; empty when it was not recorded."""
    for _, f in frames:
        if f[3] == PacketType.SYNC2:
            parts = f[4:-2].split(b"\0")
            text = [p.decode("ascii", "replace") for p in parts]
            if len(text) >= 3:
                return text[0], text[2]
    return "", ""
