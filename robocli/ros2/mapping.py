"""robocli's samples as standard ROS 2 messages (REP 103 units, REP 105 frames).

The input is what a robocli recording holds: a message of one of robocli's schemas
(:mod:`robocli.io.schemas`: the JSON dict of a ``foxglove.*`` or ``robocli.*`` schema, as the
recorder's decoders build it) and the robocli topic it belongs to (``/NAME/KEY``). The
output is zero or more ROS 2 messages, CDR-encoded, each with its topic, type and time:

>>> from robocli.ros2 import to_ros2                      # doctest: +SKIP
>>> for m in to_ros2("robocli.pioneer.State", "/pioneer/state", state_dict):
...     m.topic, m.msgtype, len(m.data), m.t_ns
('/pioneer/odom', 'nav_msgs/msg/Odometry', 724, 1764264...)

========================== ======================================================================
robocli schema (topic)     ROS 2
========================== ======================================================================
robocli.pioneer.State      ``/NAME/odom`` nav_msgs/Odometry (odom -> base_link; twist in
                           base_link: v, w), ``/NAME/battery`` sensor_msgs/BatteryState (voltage;
                           what the robot does not say is NaN), ``/diagnostics``
                           diagnostic_msgs/DiagnosticArray (motors, e-stop: ERROR, stall: WARN,
                           bumpers, digital I/O, analog)
foxglove.FrameTransform(s) ``/tf`` tf2_msgs/TFMessage
foxglove.PoseInFrame       the same topic, geometry_msgs/PoseStamped (the arm's ``tcp``; the
                           Pioneer's ``pose`` is left out: ``odom`` says it)
foxglove.LaserScan         the same topic, sensor_msgs/LaserScan (laser, sonar ring); robocli's
                           0 (no return) becomes +inf (REP 117); range_min 0.01 m, range_max
                           the larger of 30 m and the scan's farthest range
robocli.JointState         the same topic, sensor_msgs/JointState (rad, rad/s, N m)
robocli.arm.Status         ``/diagnostics``: in error or e-stopped ERROR, else OK; every flag a
                           key
robocli.Imu                ``/NAME/imu`` sensor_msgs/Imu (no orientation:
                           ``orientation_covariance[0] = -1``), ``/NAME/imu/mag``
                           sensor_msgs/MagneticField (T)
robocli.Adc                ``/NAME/adc`` std_msgs/Float64MultiArray: one dimension labelled
                           ``channel``, size 8, stride 8; ``data[i]`` is channel ``i`` in V
                           (no header: the time is the bag's)
robocli.Battery            ``/NAME/battery`` sensor_msgs/BatteryState (V, A, 0..1, cells)
robocli.SysInfo            ``/diagnostics``: temperature, load, CPU split, memory as keys
foxglove.LocationFix       ``/NAME/gps`` sensor_msgs/NavSatFix (status FIX, service GPS)
foxglove.CompressedImage   the same topic, sensor_msgs/CompressedImage
foxglove.RawImage          the same topic, sensor_msgs/Image (``rgb8``; ``mono16`` depth in mm
                           becomes ``16UC1``, the ROS depth convention)
robocli.RawFrame           the same topic, ``robocli_msgs/msg/RawFrame`` (:data:`.types.RAW_FRAME`)
std_msgs/String            the same topic, std_msgs/String (a robot's URDF on
                           ``robot_description``, its link names mapped as frames)
========================== ======================================================================

**Frames.** robocli names frames ``NAME/odom``, ``NAME/base_link``, ``NAME/laser``, the
arm's ``NAME/base`` and ``NAME/link_i`` (its URDF's links, :mod:`robocli.robots.urdf`). By
default the ``NAME/`` prefix goes: REP 105's ``odom``, ``base_link``, ``laser``, the arm's
``base`` and ``link_i`` (ROS-Industrial's names), which is what a ROS 2 tool expects of one
robot; a robot description's link names lose it too, so that its model and ``/tf`` agree.
``Mapper(prefix_frames=True)`` keeps the prefixes, for several robots in one bag or on one
ROS 2 graph.

**Bytes.** An image's (or raw frame's) ``data`` is base64 text, as in a recording's JSON,
or the bytes themselves (``bytes``, ``memoryview``), as a live sink that takes the decoders'
dicts without JSON gives them (:meth:`robocli.ros2.live.Ros2Topics.write_sample`).

**Time.** ``t_ns`` is the message's own stamp (the source's acquisition time, robocli's
``timestamp``), also written in every header. A sample of a schema not listed above maps to
nothing. A malformed sample raises :class:`~robocli.errors.RobocliError`.
"""

from __future__ import annotations

import math
import re
from typing import Any, NamedTuple

import numpy as np

from robocli.errors import RobocliError
from robocli.ros2 import types as T
from robocli.ros2.cdr import compressed_image_cdr, image_cdr, laser_scan_cdr, sample_bytes

__all__ = [
    "Mapper",
    "Ros2Message",
    "compressed_image_cdr",
    "image_cdr",
    "laser_scan_cdr",
    "to_ros2",
]

_NAN = math.nan
#: the fields of a Pioneer's and a Create's state shown in their diagnostics
_PIONEER_KEYS = ("motors_enabled", "estop", "stall_left", "stall_right", "bumpers_front",
                 "bumpers_rear", "digin", "digout", "analog", "battery", "sip_count")  # fmt: skip
_CREATE_KEYS = ("mode", "bump_left", "bump_right", "wheel_drop_left", "wheel_drop_right",
                "charging_state", "frame_count")  # fmt: skip
_F4, _F8, _U1 = np.float32, np.float64, np.uint8


class Ros2Message(NamedTuple):
    """One ROS 2 message: its topic, type (``pkg/msg/Type``), CDR bytes, and time (ns)."""

    topic: str
    msgtype: str
    data: bytes
    t_ns: int


def _ns(sample: dict[str, Any]) -> int:
    ts = sample.get("timestamp") or {}
    return int(ts.get("sec", 0)) * 1_000_000_000 + int(ts.get("nsec", 0))


class Mapper:
    """The mapping (see the module docstring); ``prefix_frames``: keep robocli's ``NAME/``
    in frame ids. Stateless but for caches: one may serve several threads."""

    def __init__(self, *, prefix_frames: bool = False) -> None:
        self.prefix_frames = prefix_frames
        self._frames: dict[str, str] = {}

    # ------------------------------------------------------------------ helpers

    def frame(self, name: str) -> str:
        """A robocli frame id as a ROS 2 one (see *Frames*)."""
        out = self._frames.get(name)
        if out is None:
            out = name if self.prefix_frames else name.split("/", 1)[-1]
            self._frames[name] = out
        return out

    def header(self, ns: int, frame_id: str) -> Any:
        """A std_msgs/Header at ``ns`` in robocli frame ``frame_id`` (mapped)."""
        return T.message("std_msgs/msg/Header", stamp=_time(ns), frame_id=self.frame(frame_id))

    # ------------------------------------------------------------------ the mapping

    @staticmethod
    def maps(kind: str) -> bool:
        """Whether samples of robocli schema ``kind`` have a mapping (some, as the
        Pioneer's pose, map to nothing: another message says it)."""
        return kind in _HANDLERS

    def map(self, kind: str, topic: str, sample: dict[str, Any]) -> list[Ros2Message]:
        """``sample`` (a message of robocli schema ``kind`` on robocli ``topic``) as ROS 2
        messages; [] for a schema with no mapping."""
        handler = _HANDLERS.get(kind)
        if handler is None:
            return []
        try:
            return handler(self, topic, sample, _ns(sample))
        except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:
            raise RobocliError(f"{topic}: a {kind} sample does not map to ROS 2 ({exc!r})"
                               ) from None  # fmt: skip

    def _one(self, topic: str, msgtype: str, ns: int, **fields: Any) -> Ros2Message:
        return Ros2Message(topic, msgtype, T.serialize(T.message(msgtype, **fields), msgtype), ns)

    def pioneer_state(self, topic: str, s: dict[str, Any], ns: int) -> list[Ros2Message]:
        estop, stall = bool(s.get("estop")), bool(s.get("stall_left") or s.get("stall_right"))
        return self._mobile(
            topic, s, ns,
            pose=_pose(s.get("x", _NAN), s.get("y", _NAN), 0.0, _quat_z(float(s.get("th", _NAN)))),
            twist=_twist(s.get("v", _NAN), s.get("w", _NAN)),
            battery=(s.get("battery", _NAN), _NAN, _NAN),
            status=(2, "emergency stop") if estop else (1, "stalled") if stall else (0, "ok"),
            keys=_PIONEER_KEYS)  # fmt: skip

    def create_state(self, topic: str, s: dict[str, Any], ns: int) -> list[Ros2Message]:
        """An iRobot Create's stream frame: odometry (its pose; no velocity in the frame),
        its battery and its bumpers, wheel drops and OI mode as diagnostics."""
        charge, capacity = float(s.get("charge", _NAN)), float(s.get("capacity", _NAN))
        drop = bool(s.get("wheel_drop_left") or s.get("wheel_drop_right"))
        bump = bool(s.get("bump_left") or s.get("bump_right"))
        return self._mobile(
            topic, s, ns,
            pose=_pose(s.get("x", _NAN), s.get("y", _NAN), 0.0, _quat_z(float(s.get("th", _NAN)))),
            twist=_twist(_NAN, _NAN),
            battery=(s.get("voltage", _NAN), s.get("current", _NAN),
                     charge / capacity if capacity > 0 else _NAN),
            status=(2, "wheel dropped") if drop else (1, "bumped") if bump else (0, "ok"),
            keys=_CREATE_KEYS)  # fmt: skip

    def _mobile(self, topic: str, s: dict[str, Any], ns: int, *, pose: Any, twist: Any,
                battery: tuple[float, float, float], status: tuple[int, str],
                keys: tuple[str, ...]) -> list[Ros2Message]:  # fmt: skip
        """A mobile robot's state ``s`` on ``/NAME/state``: its odometry (``pose``,
        ``twist``), its battery (voltage, current, state of charge) and its diagnostics
        (``status``: level and text; ``keys``: the fields of ``s`` shown)."""
        base = topic.rsplit("/", 1)[0]
        name = base.lstrip("/")
        return [
            self._one(f"{base}/odom", "nav_msgs/msg/Odometry", ns,
                      header=self.header(ns, f"{name}/odom"),
                      child_frame_id=self.frame(f"{name}/base_link"),
                      pose=_pose_cov(pose), twist=_twist_cov(twist)),
            self._battery(f"{base}/battery", ns, name, *battery, []),
            self._diagnostics(ns, name, *status, s, keys),
        ]  # fmt: skip

    def _battery(self, topic: str, ns: int, name: str, voltage: float, current: float,
                 soc: float, cells: list[float]) -> Ros2Message:  # fmt: skip
        return self._one(
            topic, "sensor_msgs/msg/BatteryState", ns, header=self.header(ns, f"{name}/battery"),
            voltage=float(voltage), temperature=_NAN, current=float(current), charge=_NAN,
            capacity=_NAN, design_capacity=_NAN, percentage=float(soc),
            power_supply_status=0, power_supply_health=0, power_supply_technology=0, present=True,
            cell_voltage=np.asarray(cells, _F4), cell_temperature=np.full(len(cells), _NAN, _F4),
            location="", serial_number="")  # fmt: skip

    def _diagnostics(self, ns: int, name: str, level: int, text: str, s: dict[str, Any],
                     keys: tuple[str, ...]) -> Ros2Message:  # fmt: skip
        values = [T.message("diagnostic_msgs/msg/KeyValue", key=k, value=_text(s[k]))
                  for k in keys if k in s]  # fmt: skip
        status = T.message("diagnostic_msgs/msg/DiagnosticStatus", level=level,
                           name=name, message=text, hardware_id=name, values=values)  # fmt: skip
        return self._one("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray", ns,
                         header=self.header(ns, ""), status=[status])  # fmt: skip

    def transforms(self, topic: str, s: dict[str, Any], ns: int) -> list[Ros2Message]:
        items = s["transforms"] if "transforms" in s else [s]
        ns = ns or (_ns(items[0]) if items else 0)  # FrameTransforms: stamped inside only
        tfs = [T.message(
            "geometry_msgs/msg/TransformStamped",
            header=self.header(_ns(t) or ns, t["parent_frame_id"]),
            child_frame_id=self.frame(t["child_frame_id"]),
            transform=T.message("geometry_msgs/msg/Transform",
                                translation=_vector3(t["translation"]),
                                rotation=_quat(t["rotation"])))
            for t in items]  # fmt: skip
        return [self._one("/tf", "tf2_msgs/msg/TFMessage", ns, transforms=tfs)]

    def pose(self, topic: str, s: dict[str, Any], ns: int) -> list[Ros2Message]:
        if topic.endswith("/pose"):  # the Pioneer's: its odom says it, with the twist
            return []
        p = s["pose"]
        return [self._one(topic, "geometry_msgs/msg/PoseStamped", ns,
                          header=self.header(ns, s["frame_id"]),
                          pose=_pose(p["position"]["x"], p["position"]["y"], p["position"]["z"],
                                     _quat(p["orientation"])))]  # fmt: skip

    def laser(self, topic: str, s: dict[str, Any], ns: int) -> list[Ros2Message]:
        data = laser_scan_cdr(ns, self.frame(s["frame_id"]), float(s["start_angle"]),
                              float(s["end_angle"]), np.asarray(s["ranges"], _F4),
                              np.asarray(s.get("intensities") or (), _F4))  # fmt: skip
        return [Ros2Message(topic, "sensor_msgs/msg/LaserScan", data, ns)]

    def joints(self, topic: str, s: dict[str, Any], ns: int) -> list[Ros2Message]:
        return [self._one(topic, "sensor_msgs/msg/JointState", ns,
                          header=self.header(ns, ""), name=list(s["name"]),
                          position=np.asarray(s.get("position") or (), _F8),
                          velocity=np.asarray(s.get("velocity") or (), _F8),
                          effort=np.asarray(s.get("effort") or (), _F8))]  # fmt: skip

    def arm_status(self, topic: str, s: dict[str, Any], ns: int) -> list[Ros2Message]:
        name = topic.rsplit("/", 1)[0].lstrip("/")
        bad = s.get("in_error") or s.get("e_stopped")
        text = "in error" if s.get("in_error") else "emergency stop" if bad else "ok"
        keys = (
            "drives_powered",
            "e_stopped",
            "in_error",
            "in_motion",
            "motion_possible",
            "mode",
            "error_code",
        )
        return [self._diagnostics(ns, name, 2 if bad else 0, text, s, keys)]

    def imu(self, topic: str, s: dict[str, Any], ns: int) -> list[Ros2Message]:
        header = self.header(ns, s["frame_id"])
        zero = np.zeros(9, _F8)
        unknown = np.zeros(9, _F8)
        unknown[0] = -1.0  # sensor_msgs/Imu: no orientation estimate
        out = [self._one(topic, "sensor_msgs/msg/Imu", ns, header=header,
                         orientation=_quat({"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}),
                         orientation_covariance=unknown,
                         angular_velocity=_vector3(s.get("angular_velocity")),
                         angular_velocity_covariance=zero,
                         linear_acceleration=_vector3(s.get("linear_acceleration")),
                         linear_acceleration_covariance=zero)]  # fmt: skip
        if "magnetic_field" in s:
            out.append(self._one(f"{topic}/mag", "sensor_msgs/msg/MagneticField", ns,
                                 header=header, magnetic_field=_vector3(s["magnetic_field"]),
                                 magnetic_field_covariance=zero))  # fmt: skip
        return out

    def adc(self, topic: str, s: dict[str, Any], ns: int) -> list[Ros2Message]:
        data = np.asarray(s.get("channels") or (), _F8)
        dim = T.message("std_msgs/msg/MultiArrayDimension", label="channel", size=len(data),
                        stride=len(data))  # fmt: skip
        layout = T.message("std_msgs/msg/MultiArrayLayout", dim=[dim], data_offset=0)
        return [self._one(topic, "std_msgs/msg/Float64MultiArray", ns, layout=layout, data=data)]

    def battery(self, topic: str, s: dict[str, Any], ns: int) -> list[Ros2Message]:
        name = topic.rsplit("/", 1)[0].lstrip("/")
        return [self._battery(topic, ns, name, s.get("voltage", _NAN), s.get("current", _NAN),
                              s.get("state_of_charge", _NAN),
                              list(s.get("cells") or ()))]  # fmt: skip

    def sysinfo(self, topic: str, s: dict[str, Any], ns: int) -> list[Ros2Message]:
        name = topic.rsplit("/", 1)[0].lstrip("/")
        flat: dict[str, Any] = {}
        for k, v in s.items():
            if isinstance(v, dict) and k != "timestamp":
                flat.update({f"{k}.{kk}": vv for kk, vv in v.items()})
            elif k != "timestamp":
                flat[k] = v
        return [self._diagnostics(ns, f"{name} computer", 0, "ok", flat, tuple(flat))]

    def gps(self, topic: str, s: dict[str, Any], ns: int) -> list[Ros2Message]:
        status = T.message("sensor_msgs/msg/NavSatStatus", status=0, service=1)
        return [
            self._one(
                topic,
                "sensor_msgs/msg/NavSatFix",
                ns,
                header=self.header(ns, s["frame_id"]),
                status=status,
                latitude=float(s.get("latitude", _NAN)),
                longitude=float(s.get("longitude", _NAN)),
                altitude=float(s.get("altitude", _NAN)),
                position_covariance=np.asarray(s.get("position_covariance") or [0.0] * 9, _F8),
                position_covariance_type=int(s.get("position_covariance_type", 0)),
            )
        ]

    def compressed(self, topic: str, s: dict[str, Any], ns: int) -> list[Ros2Message]:
        data = compressed_image_cdr(ns, self.frame(s["frame_id"]), str(s.get("format", "jpeg")),
                                    sample_bytes(s["data"]))  # fmt: skip
        return [Ros2Message(topic, "sensor_msgs/msg/CompressedImage", data, ns)]

    def image(self, topic: str, s: dict[str, Any], ns: int) -> list[Ros2Message]:
        encoding = "16UC1" if s["encoding"] == "mono16" else str(s["encoding"])
        data = image_cdr(ns, self.frame(s["frame_id"]), int(s["height"]), int(s["width"]),
                         encoding, int(s["step"]), sample_bytes(s["data"]))  # fmt: skip
        return [Ros2Message(topic, "sensor_msgs/msg/Image", data, ns)]

    def text(self, topic: str, s: dict[str, Any], ns: int) -> list[Ros2Message]:
        data = str(s["data"])
        if topic.endswith("/robot_description") and not self.prefix_frames:
            data = _URDF_LINK.sub(lambda m: m[1] + self.frame(m[2]) + m[3], data)
        return [self._one(topic, "std_msgs/msg/String", ns, data=data)]

    def raw(self, topic: str, s: dict[str, Any], ns: int) -> list[Ros2Message]:
        return [self._one(topic, T.RAW_FRAME, ns, stamp=_time(ns), link=s["link"],
                          protocol=s["protocol"], direction=s["direction"],
                          port=s.get("port", ""),
                          data=np.frombuffer(sample_bytes(s["data"]), _U1))]  # fmt: skip


_HANDLERS = {
    "robocli.pioneer.State": Mapper.pioneer_state,
    "robocli.create.State": Mapper.create_state,
    "foxglove.FrameTransform": Mapper.transforms,
    "foxglove.FrameTransforms": Mapper.transforms,
    "foxglove.PoseInFrame": Mapper.pose,
    "foxglove.LaserScan": Mapper.laser,
    "robocli.JointState": Mapper.joints,
    "robocli.arm.Status": Mapper.arm_status,
    "robocli.Imu": Mapper.imu,
    "robocli.Adc": Mapper.adc,
    "robocli.Battery": Mapper.battery,
    "robocli.SysInfo": Mapper.sysinfo,
    "foxglove.LocationFix": Mapper.gps,
    "foxglove.CompressedImage": Mapper.compressed,
    "foxglove.RawImage": Mapper.image,
    T.RAW_SCHEMA: Mapper.raw,
    "std_msgs/String": Mapper.text,
}
#: A link's name in a URDF: ``<link name="...">``, ``<parent link="...">``, ``<child link=...``.
_URDF_LINK = re.compile(r'(<(?:link\s[^>]*?\bname|(?:parent|child)\s[^>]*?\blink)=")([^"]*)(")')

_DEFAULT = Mapper()


def to_ros2(kind: str, topic: str, sample: dict[str, Any], *,
            prefix_frames: bool = False) -> list[Ros2Message]:  # fmt: skip
    """``sample`` (robocli schema ``kind``, robocli ``topic``) as ROS 2 messages: see
    :class:`Mapper`."""
    mapper = _DEFAULT if not prefix_frames else _PREFIXED
    return mapper.map(kind, topic, sample)


_PREFIXED = Mapper(prefix_frames=True)


# ---------------------------------------------------------------------- small builders


def _time(ns: int) -> Any:
    sec, nsec = divmod(int(ns), 1_000_000_000)
    return T.message("builtin_interfaces/msg/Time", sec=sec, nanosec=nsec)


def _text(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, list):
        return " ".join(_text(x) for x in v)
    return str(v)


def _vector3(v: dict[str, float] | None) -> Any:
    v = v or {}
    return T.message("geometry_msgs/msg/Vector3", x=float(v.get("x", _NAN)),
                     y=float(v.get("y", _NAN)), z=float(v.get("z", _NAN)))  # fmt: skip


def _quat(q: dict[str, float]) -> Any:
    return T.message("geometry_msgs/msg/Quaternion", x=float(q["x"]), y=float(q["y"]),
                     z=float(q["z"]), w=float(q["w"]))  # fmt: skip


def _quat_z(th: float) -> Any:
    return _quat({"x": 0.0, "y": 0.0, "z": math.sin(th / 2), "w": math.cos(th / 2)})


def _pose(x: float, y: float, z: float, q: Any) -> Any:
    point = T.message("geometry_msgs/msg/Point", x=float(x), y=float(y), z=float(z))
    return T.message("geometry_msgs/msg/Pose", position=point, orientation=q)


def _pose_cov(pose: Any) -> Any:
    return T.message("geometry_msgs/msg/PoseWithCovariance", pose=pose,
                     covariance=np.zeros(36, _F8))  # fmt: skip


def _twist(v: float, w: float) -> Any:
    return T.message("geometry_msgs/msg/Twist", linear=_vector3({"x": v, "y": 0.0, "z": 0.0}),
                     angular=_vector3({"x": 0.0, "y": 0.0, "z": w}))  # fmt: skip


def _twist_cov(twist: Any) -> Any:
    return T.message("geometry_msgs/msg/TwistWithCovariance", twist=twist,
                     covariance=np.zeros(36, _F8))  # fmt: skip
