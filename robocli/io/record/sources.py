"""What each device gives a :class:`~robocli.io.record.Recorder`, and the channels it becomes.

Each device is recorded through its public listener hooks, as python-can's writers are:

- every frame each way on each link goes, whole and unchanged, into a raw channel
  ``/NAME/raw/[PORT/]tx|rx`` (message encoding :data:`~robocli.io.record.recorder.
  RAW_ENCODING`; metadata ``protocol``, ``direction``, ``link``, ``port``), which
  ``robocli dump ... --file`` decodes again to the same packets as the live dump;
- the same frames are decoded in the writer thread (never in the device's) into channels
  with Foxglove's schemas or robocli's (:mod:`robocli.io.schemas`).

Topics, for a source named ``NAME`` (frames are ``NAME/odom``, ``NAME/base_link``...):

========== =================================================================================
Pioneer    ``pose`` (PoseInFrame in ``odom``), ``tf`` (FrameTransform odom -> base_link),
           ``sonar`` (LaserScan in ``base_link``, 360 one-degree bins, 0 where no sonar
           looks), ``laser`` (a simulator's laser, LaserScan), ``state`` (robocli.pioneer.State)
Arm        ``joint_states`` (JOINT_POSITION) and ``joint_feedback`` (JOINT_FEEDBACK, with the
           controller's time), both robocli.JointState; ``tcp`` (PoseInFrame of the flange
           in ``base``) and ``tf`` (FrameTransforms of every link), from the feedback when
           the controller sends it, else from JOINT_POSITION; ``status`` (robocli.arm.Status)
Hub        ``imu`` (robocli.Imu), ``adc``, ``battery``, ``sysinfo``, ``gps`` (LocationFix),
           ``laser`` (LaserScan), ``camera`` (CompressedImage for JPEG, else RawImage rgb8),
           ``stereo/left|right``, ``depth/rgb`` and ``depth/image`` (RawImage mono16, mm)
========== =================================================================================
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any

import numpy as np

from robocli.errors import InvalidArgument
from robocli.io import schemas as S
from robocli.io.record.recorder import RAW_ENCODING, Recorder

if TYPE_CHECKING:
    from robocli.devices.arm import Arm
    from robocli.devices.hub import Hub
    from robocli.devices.pioneer import Pioneer
    from robocli.devices.pioneer.laser import LaserScan
    from robocli.robots.pioneer import RobotParams

__all__ = ["RawLink", "attach", "pull_hub", "raw_link"]

_ENCODE = json.JSONEncoder(separators=(",", ":"), allow_nan=False).encode


def _json(message: Any) -> str:
    """Compact JSON of ``message``; NaN and infinities (no reading) become null."""
    try:
        return _ENCODE(message)
    except ValueError:
        return _ENCODE(_finite(message))


def _finite(value: Any) -> Any:
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value


_G = 9.80665  #: m/s^2 per g (the hub's IMU reports g, deg/s, uT)
_SONAR_BINS = 360
_CPU = ("user", "sys", "nice", "idle", "iowait", "hirq", "sirq")


class RawLink:
    """A listener ``(direction, payload, t)`` writing every frame of one link into its raw
    channels, then handing the payload to :attr:`decoder` (writer thread). ``reframe``
    rebuilds the whole frame from what the device's listener gets (the Pioneer's listeners
    see payloads without sync bytes and checksum)."""

    def __init__(self, rec: Recorder, name: str, protocol: str, *,
                 reframe: Callable[[bytes], bytes] | None = None, port: str | None = None,
                 **metadata: str) -> None:  # fmt: skip
        self.rec, self.name, self.protocol, self.port = rec, name, protocol, port
        self._reframe = reframe
        self._metadata = {"protocol": protocol, "link": name, **metadata}
        if port is not None:
            self._metadata["port"] = port
        self._cids: dict[str, int] = {}
        #: called as ``decoder(direction, payload, log_ns)`` after the raw message is written
        self.decoder: Callable[[str, bytes, int], None] | None = None
        self._put = rec.put
        self._handle_ref = self._handle

    def __call__(self, direction: str, payload: bytes, t: float) -> None:
        self._put(self._handle_ref, (direction, payload, t), len(payload))

    def _handle(self, direction: str, payload: bytes, t: float) -> None:
        cid = self._cids.get(direction)
        if cid is None:
            part = f"{self.port}/{direction}" if self.port else direction
            cid = self.rec.channel(f"/{self.name}/raw/{part}", None, encoding=RAW_ENCODING,
                                   metadata={**self._metadata, "direction": direction})  # fmt: skip
            self._cids[direction] = cid
        ns = self.rec.log_ns(t)
        self.rec.write(cid, self._reframe(payload) if self._reframe else payload, ns)
        if self.decoder is not None:
            self.decoder(direction, payload, ns)


def raw_link(rec: Recorder, name: str, protocol: str, **metadata: str) -> RawLink:
    """A new raw link of ``rec`` named ``name`` (``name2``... when taken): see
    :meth:`Recorder.listener`."""
    return _new_link(rec, rec.unique_name(name), protocol, **metadata)


def _new_link(rec: Recorder, name: str, protocol: str, **metadata: str) -> RawLink:
    """A raw link under ``name`` (reserved with :meth:`Recorder.unique_name`)."""
    reframe: Callable[[bytes], bytes] | None = None
    if protocol == "arcos":
        from robocli.protocols.arcos import frame

        reframe = frame
    link = RawLink(rec, name, protocol, reframe=reframe, **metadata)
    rec.links[name] = link
    return link


def attach(rec: Recorder, device: Any, name: str | None = None, **options: Any) -> str:
    """Record ``device`` into ``rec`` (see :meth:`Recorder.add`); returns its name."""
    from robocli.devices.arm import Arm
    from robocli.devices.hub import Hub
    from robocli.devices.pioneer import Pioneer

    if isinstance(device, Pioneer):
        return _attach_pioneer(rec, device, name, **options)
    if isinstance(device, Arm):
        return _attach_arm(rec, device, name or "arm", **options)
    if isinstance(device, Hub):
        return _attach_hub(rec, device, name or "hub", **options)
    raise InvalidArgument(f"cannot record a {type(device).__name__}: give a Pioneer, an Arm "
                          "or a Hub")  # fmt: skip


# ---------------------------------------------------------------------- Pioneer


def _attach_pioneer(rec: Recorder, robot: Pioneer, name: str | None) -> str:
    """``name``: the default ``pioneer`` (numbered), or the name of a link made with
    :meth:`Recorder.listener` at connect time, which then gets decoded."""
    link: RawLink | None = rec.links.get(name) if name is not None else None
    if link is not None and link.decoder is not None:
        raise InvalidArgument(f"{name!r} is recorded already")
    if link is None:  # not listening since the handshake: from now on
        name = rec.unique_name(name or "pioneer")
        link = _new_link(rec, name, "arcos", url=robot.transport.url)
        robot.add_listener(link)
        rec.on_close(lambda: robot.remove_listener(link))
    assert name is not None
    decoder = PioneerDecoder(rec, name, robot.params)
    link.decoder = decoder
    put = rec.put
    on_scan = decoder.scan

    def laser(scan: LaserScan) -> None:
        put(on_scan, (scan,), 8 * len(scan.ranges))

    robot.on_laser(laser)
    rec.on_close(lambda: robot.remove_laser_listener(laser))
    return name


class PioneerDecoder:
    """SIPs (writer thread) -> pose, transform, sonar scan, state; laser scans -> LaserScan.

    Keeps its own odometry (the 15-bit counters unwrapped as the client does, SETO seen in
    the frames sent), so that every recorded pose belongs to the SIP it was decoded from."""

    def __init__(self, rec: Recorder, name: str, params: RobotParams) -> None:
        from robocli.devices.pioneer.state import Odometry

        self.rec, self.params = rec, params
        self.odo = Odometry()
        n = max(16, len(params.sonar))
        self.sonar = [math.nan] * n
        self.sips = 0
        self.odom, self.base = f"{name}/odom", f"{name}/base_link"
        self.topics = {k: f"/{name}/{k}" for k in ("pose", "tf", "sonar", "laser", "state")}
        self._cids: dict[str, int] = {}
        self._step = 2 * math.pi / _SONAR_BINS

    def _cid(self, key: str, schema: str) -> int:
        cid = self._cids.get(key)
        if cid is None:
            cid = self._cids[key] = self.rec.channel(self.topics[key], schema)
        return cid

    def __call__(self, direction: str, payload: bytes, ns: int) -> None:
        from robocli.protocols.arcos import Command

        ptype = payload[0]
        if direction == "tx":
            if ptype == Command.SETO:
                self.odo.expect_reset()
            return
        if ptype & 0xF0 != 0x30:
            return  # not a SIP
        self._sip(payload[1:], ns)

    def _sip(self, body: bytes, ns: int) -> None:
        from robocli.devices.pioneer.state import build_state
        from robocli.protocols.arcos import decode_sip

        sip = decode_sip(body)
        odo = self.odo.update(sip["x"], sip["y"])
        conv = self.params.range_conv / 1000.0
        sonar = self.sonar
        for number, rng in sip["sonar"]:
            if number < len(sonar):
                sonar[number] = rng * conv
        self.sips += 1
        st = build_state(sip, 0.0, odo, tuple(sonar), (), self.params, self.sips)
        sec, nsec = divmod(ns, 1_000_000_000)
        qz, qw = math.sin(st.th / 2), math.cos(st.th / 2)
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
        rec.write(self._cid("sonar", "foxglove.LaserScan"), self._sonar_scan(ns), ns)
        state = {
            "timestamp": {"sec": sec, "nsec": nsec}, "x": st.x, "y": st.y, "th": st.th,
            "v": st.v, "w": st.w, "left_velocity": st.left_velocity,
            "right_velocity": st.right_velocity, "battery": st.battery,
            "motors_enabled": st.motors_enabled, "estop": st.estop,
            "stall_left": st.stall_left, "stall_right": st.stall_right,
            "bumpers_front": st.bumpers_front, "bumpers_rear": st.bumpers_rear,
            "sonar": [r if r == r else None for r in sonar[: len(self.params.sonar)]],
            "digin": st.digin, "digout": st.digout, "analog": st.analog, "sip_count": self.sips,
        }  # fmt: skip
        rec.write(self._cid("state", "robocli.pioneer.State"), _json(state).encode(), ns)

    def _sonar_scan(self, ns: int) -> bytes:
        """The latest sonar ranges as a 360-bin scan about base_link: each echo point (from
        the transducer's position and heading) at its own bearing and distance."""
        bins = [0.0] * _SONAR_BINS
        step = self._step
        for pose, r in zip(self.params.sonar, self.sonar, strict=False):
            if not 0 < r < math.inf:
                continue
            px = pose.x + r * math.cos(pose.th)
            py = pose.y + r * math.sin(pose.th)
            k = round((math.atan2(py, px) + math.pi) / step) % _SONAR_BINS
            bins[k] = round(math.hypot(px, py), 4)
        scan = S.laser_scan(ns, self.base, -math.pi, math.pi - step, bins)
        return _json(scan).encode()

    def scan(self, scan: LaserScan) -> None:
        """A simulator's laser scan (writer thread)."""
        ns = self.rec.log_ns(scan.t)
        angles = scan.angles
        if not angles:
            return
        data = S.laser_scan(ns, self.base, angles[0], angles[-1], list(scan.ranges),
                            [float(v) for v in scan.reflectance or ()])  # fmt: skip
        self.rec.write(self._cid("laser", "foxglove.LaserScan"), _json(data).encode(), ns)


# ---------------------------------------------------------------------- Arm


def _attach_arm(rec: Recorder, arm: Arm, name: str, ports: str = "both") -> str:
    name = rec.unique_name(name)
    order = "big" if arm.byteorder == ">" else "little"
    if ports not in ("both", "motion", "state"):
        raise InvalidArgument(f"ports must be 'motion', 'state' or 'both', not {ports!r}")
    decoder = ArmDecoder(rec, name, arm)
    protocol = "sm-be" if arm.byteorder == ">" else "sm-le"
    for port in arm.stats:  # the ports this Arm opened
        if ports not in ("both", port):
            continue
        link = RawLink(rec, name, protocol, port=port, byte_order=order, real_size=str(arm.real))
        if port == "state":
            link.decoder = decoder
        arm.add_listener(link, ports=port)
        rec.on_close(_detach_arm(arm, link, port))
    return name


def _detach_arm(arm: Arm, link: RawLink, port: str) -> Callable[[], None]:
    return lambda: arm.remove_listener(link, ports=port)


class ArmDecoder:
    """State-port frames (writer thread) -> joint states, flange pose, link frames, status.

    The controller's clock (JOINT_FEEDBACK's time) is put on the host clock by the smallest
    receive-minus-controller time seen so far (the transport delay's floor is taken as 0)."""

    def __init__(self, rec: Recorder, name: str, arm: Arm) -> None:
        self.rec, self.model = rec, arm.robot
        self.order, self.real = arm.byteorder, arm.real
        n = self.model.n_joints
        self.names = [f"joint_{i + 1}" for i in range(n)]
        self.frames = [f"{name}/base", *(f"{name}/link_{i + 1}" for i in range(n))]
        self.topics = {k: f"/{name}/{k}" for k in
                       ("joint_states", "joint_feedback", "tcp", "tf", "status")}  # fmt: skip
        self.offset: float | None = None  #: host epoch s minus controller s (min so far)
        self._feedback = False  # JOINT_FEEDBACK seen: the frames follow it
        self._cids: dict[str, int] = {}
        dh = zip(self.model.a, self.model.d, self.model.alpha, self.model.offset, strict=True)
        self._dh = [(float(a), float(d), math.cos(al), math.sin(al), float(off))
                    for a, d, al, off in dh]  # fmt: skip

    def _cid(self, key: str, schema: str) -> int:
        cid = self._cids.get(key)
        if cid is None:
            cid = self._cids[key] = self.rec.channel(self.topics[key], schema)
        return cid

    def __call__(self, direction: str, frame: bytes, ns: int) -> None:
        from robocli.protocols import simple_message as sm
        from robocli.protocols.simple_message import MsgType, ValidFields

        if direction != "rx":
            return
        msg = sm.decode(frame, byteorder=self.order, real=self.real)
        body = msg.body
        if not isinstance(body, dict):
            return
        n = self.model.n_joints
        if msg.msg_type == MsgType.JOINT_POSITION:
            self._joints("joint_states", ns, ns, list(body["joints"][:n]), [], None)
        elif msg.msg_type == MsgType.JOINT_FEEDBACK and body["valid_fields"] & ValidFields.POSITION:
            valid = body["valid_fields"]
            rt = float(body["time"]) if valid & ValidFields.TIME else None
            publish = ns
            if rt is not None:
                seen = ns / 1e9 - rt
                self.offset = seen if self.offset is None else min(self.offset, seen)
                publish = min(ns, int((rt + self.offset) * 1e9))  # (float rounding)
            vel = list(body["velocities"][:n]) if valid & ValidFields.VELOCITY else []
            self._feedback = True
            self._joints("joint_feedback", ns, publish, list(body["positions"][:n]), vel, rt)
        elif msg.msg_type == MsgType.STATUS:
            from robocli.devices.arm.state import ArmStatus

            status = ArmStatus.from_body(body, 0.0).as_dict()
            status["timestamp"] = S.stamp(ns)
            self.rec.write(self._cid("status", "robocli.arm.Status"), _json(status).encode(), ns)

    def _joints(self, topic: str, ns: int, publish: int, q: list[float], vel: list[float],
                robot_time: float | None) -> None:  # fmt: skip
        rec = self.rec
        stamp = S.stamp(publish)
        source = "joint_feedback" if topic == "joint_feedback" else "joint_position"
        state = {"timestamp": stamp, "name": self.names, "position": q, "velocity": vel,
                 "effort": [], "source": source, "robot_time": robot_time}  # fmt: skip
        rec.write(self._cid(topic, "robocli.JointState"), _json(state).encode(), ns, publish)
        if self._feedback and topic != "joint_feedback":
            return  # the frames follow the feedback, on the controller's clock
        transforms = []
        rot = np.eye(3)
        pos = np.zeros(3)
        for i, (theta, (a, d, ca, sa, off)) in enumerate(zip(q, self._dh, strict=False)):
            ct, st = math.cos(theta + off), math.sin(theta + off)
            # standard DH: Rz(theta) Tz(d) Tx(a) Rx(alpha)
            r = np.array([[ct, -st * ca, st * sa], [st, ct * ca, -ct * sa], [0.0, sa, ca]])
            t = (a * ct, a * st, d)
            transforms.append(S.frame_transform(publish, self.frames[i], self.frames[i + 1], t,
                                                _quaternion(r)))  # fmt: skip
            pos = pos + rot @ np.array(t)
            rot = rot @ r
        rec.write(self._cid("tf", "foxglove.FrameTransforms"),
                  _json({"transforms": transforms}).encode(), ns, publish)  # fmt: skip
        x, y, z = (float(v) for v in pos)
        tcp = {"timestamp": stamp, "frame_id": self.frames[0],
               "pose": S.pose(x, y, z, _quaternion(rot))}  # fmt: skip
        rec.write(self._cid("tcp", "foxglove.PoseInFrame"), _json(tcp).encode(), ns, publish)


def _quaternion(r: Any) -> dict[str, float]:
    """The unit quaternion of a 3 x 3 rotation matrix (Shepperd's method)."""
    m00, m11, m22 = float(r[0, 0]), float(r[1, 1]), float(r[2, 2])
    trace = m00 + m11 + m22
    if trace > 0:
        s = 2.0 * math.sqrt(trace + 1.0)
        w, x = 0.25 * s, (float(r[2, 1]) - float(r[1, 2])) / s
        y, z = (float(r[0, 2]) - float(r[2, 0])) / s, (float(r[1, 0]) - float(r[0, 1])) / s
    elif m00 > m11 and m00 > m22:
        s = 2.0 * math.sqrt(1.0 + m00 - m11 - m22)
        w, x = (float(r[2, 1]) - float(r[1, 2])) / s, 0.25 * s
        y, z = (float(r[0, 1]) + float(r[1, 0])) / s, (float(r[0, 2]) + float(r[2, 0])) / s
    elif m11 > m22:
        s = 2.0 * math.sqrt(1.0 + m11 - m00 - m22)
        w, x = (float(r[0, 2]) - float(r[2, 0])) / s, (float(r[0, 1]) + float(r[1, 0])) / s
        y, z = 0.25 * s, (float(r[1, 2]) + float(r[2, 1])) / s
    else:
        s = 2.0 * math.sqrt(1.0 + m22 - m00 - m11)
        w, x = (float(r[1, 0]) - float(r[0, 1])) / s, (float(r[0, 2]) + float(r[2, 0])) / s
        y, z = (float(r[1, 2]) + float(r[2, 1])) / s, 0.25 * s
    return {"x": x, "y": y, "z": z, "w": w}


# ---------------------------------------------------------------------- Hub


def _attach_hub(rec: Recorder, hub: Hub, name: str, sensors: Iterable[str] = ()) -> str:
    name = rec.unique_name(name)
    link = RawLink(rec, name, "ros4mat", url=hub.url, sensors=",".join(sensors))
    link.decoder = HubDecoder(rec, name, hub)
    hub.session.listeners.add(link)
    rec.on_close(lambda: hub.session.listeners.remove(link))
    return name


class HubDecoder:
    """Data replies (writer thread) -> one message per sample, published at the sample's
    acquisition time on the host clock (the hub's time minus the client's offset estimate)."""

    def __init__(self, rec: Recorder, name: str, hub: Hub) -> None:
        self.rec, self.hub, self.name = rec, hub, name
        self._cids: dict[str, int] = {}

    def _cid(self, topic: str, schema: str) -> int:
        cid = self._cids.get(topic)
        if cid is None:
            cid = self._cids[topic] = self.rec.channel(f"/{self.name}/{topic}", schema)
        return cid

    def __call__(self, direction: str, frame: bytes, ns: int) -> None:
        from robocli.devices.hub_decode import HEADER, body_of
        from robocli.protocols.ros4mat import MsgType

        if direction != "rx" or len(frame) < HEADER.size:
            return
        header = HEADER.unpack_from(frame, 0)
        mtype, error, n = header[0], header[1], header[3]
        if error or not n or mtype not in _HUB_HANDLERS:
            return
        _, body = body_of(frame)
        offset = self.hub.sync.offset or 0.0
        _HUB_HANDLERS[mtype](self, MsgType(mtype), body, n, ns, offset)

    def _put(self, topic: str, schema: str, message: dict[str, Any], ns: int, t: float,
             offset: float) -> None:  # fmt: skip
        publish = int((t - offset) * 1e9)
        message["timestamp"] = S.stamp(publish)
        self.rec.write(self._cid(topic, schema), _json(message).encode(), ns, publish)

    def fixed(self, mtype: Any, body: Any, n: int, ns: int, offset: float) -> None:
        from robocli.protocols.ros4mat import MsgType, record_dtype

        rec = np.frombuffer(body, dtype=record_dtype(mtype), count=n)
        f = {name: rec[name].tolist() for name in rec.dtype.names or ()}  # Python numbers
        frame_id = f"{self.name}/{mtype.name.lower()}"
        put = self._put
        for i, t in enumerate(f["t"]):
            if mtype == MsgType.ADC:
                put("adc", "robocli.Adc", {"channels": f["channels"][i]}, ns, t, offset)
            elif mtype == MsgType.IMU:
                put("imu", "robocli.Imu", {
                    "frame_id": frame_id,
                    "linear_acceleration": _xyz([v * _G for v in f["acc"][i]]),
                    "angular_velocity": _xyz([math.radians(v) for v in f["gyro"][i]]),
                    "magnetic_field": _xyz([v * 1e-6 for v in f["mag"][i]]),
                }, ns, t, offset)  # fmt: skip
            elif mtype == MsgType.GPS:
                fix = S.location_fix(0, frame_id, f["latitude"][i], f["longitude"][i],
                                     f["altitude"][i])  # fmt: skip
                put("gps", "foxglove.LocationFix", fix, ns, t, offset)
            elif mtype == MsgType.COMPUTER:
                put("sysinfo", "robocli.SysInfo", {
                    "cpu_temperature": f["cpu_temperature"][i], "load": f["unix_load"][i],
                    "cpu": dict(zip(_CPU, f["cpu_load"][i], strict=True)),
                    "memory": dict(zip(("used", "free", "buffers"), f["memory"][i], strict=True)),
                    "state": f["state"][i],
                }, ns, t, offset)  # fmt: skip
            else:  # BATTERY
                put("battery", "robocli.Battery", {
                    "voltage": f["vtotal"][i], "current": f["current"][i],
                    "cells": f["vcell"][i][: f["n_cells"][i]], "state": f["state"][i],
                    "state_of_charge": f["state_of_charge"][i],
                }, ns, t, offset)  # fmt: skip

    def laser(self, mtype: Any, body: Any, n: int, ns: int, offset: float) -> None:
        from robocli.protocols.ros4mat import record_dtype

        dtype = record_dtype(mtype)
        infos = np.frombuffer(body, dtype=dtype, count=n)
        pos = n * dtype.itemsize
        frame_id = f"{self.name}/laser"
        for info in infos:
            size = int(info["size_data"])
            ranges = np.frombuffer(body, dtype="<f4", count=size // 4, offset=pos).tolist()
            pos += size
            scan = S.laser_scan(0, frame_id, float(info["angle_min"]), float(info["angle_max"]),
                                ranges)  # fmt: skip
            self._put("laser", "foxglove.LaserScan", scan, ns, float(info["t"]), offset)

    def images(self, mtype: Any, body: Any, n: int, ns: int, offset: float) -> None:
        from robocli.protocols.ros4mat import MsgType, record_dtype

        dtype = record_dtype(mtype)
        view = memoryview(body)
        if mtype == MsgType.KINECT:
            infos = np.frombuffer(body, dtype=dtype, count=n)
            pos = n * dtype.itemsize
            for info in infos:
                for part, topic in (("rgb", "depth/rgb"), ("depth", "depth/image")):
                    pos = self._image(topic, info[part], view, pos, ns, offset,
                                      depth=part == "depth")  # fmt: skip
            return
        count = 2 * n if mtype == MsgType.WEBCAM_STEREO else n
        infos = np.frombuffer(body, dtype=dtype, count=count)
        pos = count * dtype.itemsize
        for k, info in enumerate(infos):
            topic = ("stereo/left", "stereo/right")[k % 2] if count != n else "camera"
            pos = self._image(topic, info, view, pos, ns, offset)

    def _image(self, topic: str, info: Any, view: memoryview, pos: int, ns: int, offset: float,
               depth: bool = False) -> int:  # fmt: skip
        size, width, height = int(info["size_data"]), int(info["width"]), int(info["height"])
        blob = view[pos : pos + size]
        frame_id = f"{self.name}/{topic.split('/')[0]}"
        if len(blob) != size:
            raise InvalidArgument(f"hub {topic}: image of {size} bytes past the reply's end")
        if int(info["compression"]) != 0:
            msg = S.compressed_image(0, frame_id, bytes(blob), "jpeg")
            self._put(topic, "foxglove.CompressedImage", msg, ns, float(info["t"]), offset)
        else:
            encoding, step = ("mono16", width * 2) if depth else ("rgb8", width * 3)
            msg = S.raw_image(0, frame_id, width, height, encoding, step, blob)
            self._put(topic, "foxglove.RawImage", msg, ns, float(info["t"]), offset)
        return pos + size


def _xyz(v: list[float]) -> dict[str, float]:
    return {"x": v[0], "y": v[1], "z": v[2]}


def _hub_handlers() -> dict[int, Callable[..., None]]:
    from robocli.protocols.ros4mat import MsgType

    return {
        MsgType.ADC: HubDecoder.fixed, MsgType.IMU: HubDecoder.fixed,
        MsgType.GPS: HubDecoder.fixed, MsgType.COMPUTER: HubDecoder.fixed,
        MsgType.BATTERY: HubDecoder.fixed, MsgType.HOKUYO: HubDecoder.laser,
        MsgType.WEBCAM: HubDecoder.images, MsgType.WEBCAM_STEREO: HubDecoder.images,
        MsgType.KINECT: HubDecoder.images,
    }  # fmt: skip


_HUB_HANDLERS = _hub_handlers()


def pull_hub(hub: Hub, sensors: Iterable[str], poll_hz: float,
             done: Callable[[], bool]) -> None:  # fmt: skip
    """Pull each of ``sensors`` (already subscribed) ``poll_hz`` times a second until
    ``done()`` is true or the link fails (its error raises). A recorder added to ``hub``
    records every reply."""
    names = list(sensors)
    if not poll_hz > 0:
        raise InvalidArgument(f"poll_hz must be positive, not {poll_hz!r}")
    period = 1.0 / poll_hz
    due = time.monotonic()
    while not done():
        for sensor in names:
            hub.read(sensor)
        due += period
        now = time.monotonic()
        if due > now:
            time.sleep(min(due - now, period))
        else:
            due = now  # behind: pull again at once, without a burst to catch up
