"""The Pioneer's channels: SIPs -> pose, odom -> base_link, sonar scan, state; a simulator's
laser scans (see :mod:`.sources` for the topics)."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from robocli.devices.pioneer.state import Odometry, build_state
from robocli.errors import InvalidArgument
from robocli.io import schemas as S
from robocli.io.record.links import RawLink, Sink, TopicDecoder, json_text, new_link, record_scans
from robocli.protocols.arcos import Command, decode_sip

if TYPE_CHECKING:
    from robocli.devices.pioneer import Pioneer
    from robocli.devices.pioneer.laser import LaserScan
    from robocli.robots.pioneer import RobotParams

__all__ = ["PioneerDecoder", "attach_pioneer"]

_SONAR_BINS = 360
_ZEROS = ["0"] * _SONAR_BINS
#: Echoes remembered by (sonar, range): ranges come in whole raw units and repeat.
_ECHO_CACHE = 1 << 16


def attach_pioneer(rec: Sink, robot: Pioneer, name: str | None) -> str:
    """``name``: the default ``pioneer`` (numbered), or the name of a link made with
    :meth:`Recorder.listener` at connect time, which then gets decoded."""
    link: RawLink | None = rec.links.get(name) if name is not None else None
    if link is not None and link.decoder is not None:
        raise InvalidArgument(f"{name!r} is recorded already")
    if link is None:  # not listening since the handshake: from now on
        name = rec.unique_name(name or "pioneer")
        link = new_link(rec, name, "arcos", url=robot.transport.url)
        robot.add_listener(link)
        rec.on_close(lambda: robot.remove_listener(link))
    assert name is not None
    from robocli.io.record.models import add_model
    from robocli.robots.urdf import pioneer_urdf

    add_model(rec, name, pioneer_urdf(robot.params, f"{name}/"))
    decoder = PioneerDecoder(rec, name, robot.params)
    link.decoder = decoder
    record_scans(rec, robot, "laser", decoder.scan)
    return name


class PioneerDecoder(TopicDecoder):
    """SIPs (writer thread) -> pose, transform, sonar scan, state; laser scans -> LaserScan.

    Keeps its own odometry (the 15-bit counters unwrapped as the client does, SETO seen in
    the frames sent), so that every recorded pose belongs to the SIP it was decoded from."""

    def __init__(self, rec: Sink, name: str, params: RobotParams) -> None:
        super().__init__(rec, name, ("pose", "tf", "sonar", "laser", "state"))
        self.params = params
        self.odo = Odometry()
        n = max(16, len(params.sonar))
        self.sonar = [math.nan] * n
        self.sips = 0
        self.odom, self.base = f"{name}/odom", f"{name}/base_link"
        #: a sink that takes the samples as dicts (a live ROS 2 one): the state first, no JSON
        self._direct: Callable[..., None] | None = getattr(rec, "write_sample", None)
        self._step = step = 2 * math.pi / _SONAR_BINS
        # per transducer: (x, y, cos th, sin th); the scan's JSON around its ranges
        self._sonar_geometry = [(p.x, p.y, math.cos(p.th), math.sin(p.th)) for p in params.sonar]
        self._echoes: dict[tuple[int, float], tuple[int, str] | None] = {}
        self._texts: dict[float, str] = {}  # sonar ranges as JSON numbers
        self._n_sonar = len(params.sonar)
        self._sonar_json = (f',"frame_id":"{self.base}","pose":{json_text(S.pose())},'
                            f'"start_angle":{-math.pi!r},"end_angle":{math.pi - step!r},'
                            '"ranges":[')  # fmt: skip

    def __call__(self, direction: str, payload: bytes, ns: int) -> None:
        ptype = payload[0]
        if direction == "tx":
            if ptype == Command.SETO:
                self.odo.expect_reset(ns / 1e9)
            return
        if ptype & 0xF0 != 0x30:
            return  # not a SIP
        self._sip(payload[1:], ns)

    def _sip(self, body: bytes, ns: int) -> None:
        sip = decode_sip(body)
        odo = self.odo.update(sip["x"], sip["y"], ns / 1e9)
        conv = self.params.range_conv / 1000.0
        sonar = self.sonar
        for number, rng in sip["sonar"]:
            if number < len(sonar):
                sonar[number] = rng * conv
        self.sips += 1
        st = build_state(sip, 0.0, odo, tuple(sonar), (), self.params, self.sips)
        sec, nsec = divmod(ns, 1_000_000_000)
        qz, qw = math.sin(st.th / 2), math.cos(st.th / 2)
        if self._direct is not None:
            self._sip_direct(st, ns, sec, nsec, sonar)
            return
        stamp = f'{{"sec":{sec},"nsec":{nsec}}}'
        quat = f'{{"x":0.0,"y":0.0,"z":{qz!r},"w":{qw!r}}}'
        xyz = f'{{"x":{st.x!r},"y":{st.y!r},"z":0.0}}'
        rec = self.rec
        rec.write(self._cid("pose", "foxglove.PoseInFrame"),
                  f'{{"timestamp":{stamp},"frame_id":"{self.odom}","pose":{{"position":{xyz},'
                  f'"orientation":{quat}}}}}'.encode(), ns)  # fmt: skip
        rec.write(self._cid("tf", "foxglove.FrameTransform"),
                  f'{{"timestamp":{stamp},"parent_frame_id":"{self.odom}","child_frame_id":'
                  f'"{self.base}","translation":{xyz},"rotation":{quat}}}'.encode(),
                  ns)  # fmt: skip
        rec.write(self._cid("sonar", "foxglove.LaserScan"), self._sonar_scan(stamp), ns)
        rec.write(self._cid("state", "robocli.pioneer.State"), self._state(st, stamp, sonar), ns)

    def _sip_direct(self, st: Any, ns: int, sec: int, nsec: int, sonar: list[float]) -> None:
        """A SIP into a sink of dicts: the state first (the odometry a ROS 2 node waits
        for), then the transform, the pose, the sonar scan (the same messages as the JSON)."""
        stamp = {"sec": sec, "nsec": nsec}
        direct = self._direct
        assert direct is not None
        direct(self._cid("state", "robocli.pioneer.State"), self._state_dict(st, stamp, sonar),
               ns)  # fmt: skip
        quat = S.quaternion_z(st.th)
        xyz = {"x": st.x, "y": st.y, "z": 0.0}
        direct(self._cid("tf", "foxglove.FrameTransform"),
               {"timestamp": stamp, "parent_frame_id": self.odom, "child_frame_id": self.base,
                "translation": xyz, "rotation": quat}, ns)  # fmt: skip
        direct(self._cid("pose", "foxglove.PoseInFrame"),
               {"timestamp": stamp, "frame_id": self.odom,
                "pose": {"position": xyz, "orientation": quat}}, ns)  # fmt: skip
        self.rec.write(self._cid("sonar", "foxglove.LaserScan"),
                       self._sonar_scan(f'{{"sec":{sec},"nsec":{nsec}}}'), ns)  # fmt: skip

    def _state(self, st: Any, stamp: str, sonar: list[float]) -> bytes:
        """The state message, written as text (this runs for every SIP): the same JSON as
        ``json_text`` of its dict, which it falls back to for a NaN or an infinity (left
        out). A sonar without a reading yet is 0, and false in ``sonar_known``."""
        if not math.isfinite(st.x + st.y + st.th + st.v + st.w + st.left_velocity
                             + st.right_velocity + st.battery + st.analog):  # fmt: skip
            # left out: what is not a number
            return json_text(self._state_dict(st, json.loads(stamp), sonar)).encode()
        texts = self._texts
        if len(texts) > _ECHO_CACHE:
            texts.clear()
        ranges, known = [], []
        for r in sonar[: self._n_sonar]:
            if math.isfinite(r):
                text = texts.get(r)
                if text is None:
                    text = texts[r] = repr(r)
                ranges.append(text)
                known.append("true")
            else:  # (NaN is no key: it equals nothing)
                ranges.append("0.0")
                known.append("false")
        b = ("false", "true")
        text = (f'{{"timestamp":{stamp},"x":{st.x!r},"y":{st.y!r},"th":{st.th!r},"v":{st.v!r},'
                f'"w":{st.w!r},"left_velocity":{st.left_velocity!r},"right_velocity":'
                f'{st.right_velocity!r},"battery":{st.battery!r},"motors_enabled":'
                f'{b[st.motors_enabled]},"estop":{b[st.estop]},"stall_left":'
                f'{b[st.stall_left]},"stall_right":{b[st.stall_right]},"bumpers_front":'
                f'{st.bumpers_front:d},"bumpers_rear":{st.bumpers_rear:d},"sonar":'
                f'[{",".join(ranges)}],"sonar_known":[{",".join(known)}],"digin":{st.digin:d},'
                f'"digout":{st.digout:d},'
                f'"analog":{st.analog!r},"sip_count":{self.sips:d}}}')  # fmt: skip
        return text.encode()

    def _state_dict(self, st: Any, stamp: dict[str, int], sonar: list[float]) -> dict[str, Any]:
        return {
            "timestamp": stamp, "x": st.x, "y": st.y, "th": st.th,
            "v": st.v, "w": st.w, "left_velocity": st.left_velocity,
            "right_velocity": st.right_velocity, "battery": st.battery,
            "motors_enabled": st.motors_enabled, "estop": st.estop,
            "stall_left": st.stall_left, "stall_right": st.stall_right,
            "bumpers_front": st.bumpers_front, "bumpers_rear": st.bumpers_rear,
            "sonar": [r if math.isfinite(r) else 0.0 for r in sonar[: self._n_sonar]],
            "sonar_known": [math.isfinite(r) for r in sonar[: self._n_sonar]],
            "digin": st.digin, "digout": st.digout, "analog": st.analog, "sip_count": self.sips,
        }  # fmt: skip

    def _sonar_scan(self, stamp: str) -> bytes:
        """The latest sonar ranges as a 360-bin scan about base_link: each echo point (from
        the transducer's position and heading) at its own bearing and distance (0 in the
        bins no sonar looks into). Written as text: this runs for every SIP."""
        bins = _ZEROS.copy()
        cache = self._echoes
        if len(cache) > _ECHO_CACHE:
            cache.clear()
        for i, r in enumerate(self.sonar[: len(self._sonar_geometry)]):
            echo = cache.get((i, r))
            if echo is None:
                echo = cache[(i, r)] = self._echo(i, r)
            if echo is not None:
                bins[echo[0]] = echo[1]
        return (
            f'{{"timestamp":{stamp}{self._sonar_json}{",".join(bins)}],"intensities":[]}}'
        ).encode()

    def _echo(self, i: int, r: float) -> tuple[int, str] | None:
        """(bin, distance text) of sonar ``i``'s echo at range ``r`` (None: no echo)."""
        if not 0 < r < math.inf:
            return None
        x, y, c, s = self._sonar_geometry[i]
        px, py = x + r * c, y + r * s
        k = round((math.atan2(py, px) + math.pi) / self._step) % _SONAR_BINS
        return k, repr(round(math.hypot(px, py), 4))

    def scan(self, scan: LaserScan) -> None:
        """A simulator's laser scan (writer thread)."""
        ns = self.rec.log_ns(scan.t)
        angles = scan.angles
        if not angles:
            return
        data = S.laser_scan(ns, self.base, angles[0], angles[-1], list(scan.ranges),
                            [float(v) for v in scan.reflectance or ()])  # fmt: skip
        self.rec.write(self._cid("laser", "foxglove.LaserScan"), json_text(data).encode(), ns)
