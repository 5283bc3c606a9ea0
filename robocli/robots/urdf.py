"""URDF descriptions of robocli's robots, generated from the data robocli itself computes with.

A Pioneer's URDF comes from its :class:`~robocli.robots.pioneer.RobotParams` (body, wheels
from ``diff_conv``'s track, the sonar ring, the laser mount); an arm's from its kinematic
model file (:func:`robocli.kinematics.load_model`), so a viewer's robot and robocli's
kinematics cannot disagree:

>>> from robocli.robots.urdf import urdf
>>> xml = urdf("irb120")                       # or "p3dx", any Pioneer subtype or arm model
>>> xml = urdf("p3dx", prefix="pioneer/")      # link names as a recording's frames

An arm's link ``link_i`` is the frame that turns with joint ``i``, at that joint's axis (the
usual URDF layout): joint ``i`` goes from ``link_{i-1}`` (``base`` for the first) to
``link_i`` at :func:`joint_origins` ``[i]`` times a rotation of ``q_i`` about z, the DH
offset being part of the origin, so that a URDF joint value is robocli's joint value. The
flange is ``flange``, fixed on the last link. The transforms of :func:`arm_transforms` are
what a recording and a live view send on the arm's ``tf``.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from robocli.errors import InvalidArgument
from robocli.kinematics.model import FloatArray, RobotModel
from robocli.robots.pioneer import ROBOT_PARAMS, RobotParams

__all__ = ["arm_transforms", "arm_urdf", "joint_origins", "known_robots", "pioneer_urdf",
           "rpy", "urdf"]  # fmt: skip

_GIMBAL = 1e-12  #: below this, cos(pitch) is taken as 0 (the yaw is folded into the roll)
_ARM_RADIUS = 0.04  #: m, the arm's links drawn as cylinders of this radius
_GREY, _ORANGE, _BLACK, _RED = "0.6 0.6 0.6 1", "0.95 0.45 0.1 1", "0.1 0.1 0.1 1", "0.8 0.1 0.1 1"


def known_robots() -> list[str]:
    """Names :func:`urdf` takes: the Pioneer subtypes and the shipped arm models."""
    from robocli.kinematics.model import known_models

    return sorted([*ROBOT_PARAMS, *known_models()])


def urdf(name: str, prefix: str = "") -> str:
    """The URDF (XML text) of the robot ``name``: a Pioneer subtype (``p3dx``...) or an arm
    model (``irb120``...). ``prefix`` goes before every link name (``"pioneer/"`` gives
    ``pioneer/base_link``, the frame names of robocli's recordings); joint names stay as
    robocli's joint states name them. Raises :class:`InvalidArgument` for an unknown name."""
    key = name.strip().lower()
    if key in ROBOT_PARAMS:
        return pioneer_urdf(ROBOT_PARAMS[key], prefix)
    from robocli.kinematics.errors import UnknownModelError
    from robocli.kinematics.model import known_models, load_model

    if key.replace("-", "").replace("_", "") in known_models():
        try:
            return arm_urdf(load_model(key), prefix)
        except UnknownModelError:  # pragma: no cover - listed, so it loads
            pass
    raise InvalidArgument(f"no robot model {name!r}; known: {', '.join(known_robots())}")


# -- transforms ----------------------------------------------------------------------------


def _rz(t: float) -> FloatArray:
    c, s = math.cos(t), math.sin(t)
    m = np.eye(4)
    m[:2, :2] = [[c, -s], [s, c]]
    return m


def _dh_link(model: RobotModel, i: int) -> FloatArray:
    """``Tz(d_i) Tx(a_i) Rx(alpha_i)``: the fixed part of DH link ``i`` (0-based)."""
    ca, sa = math.cos(float(model.alpha[i])), math.sin(float(model.alpha[i]))
    m = np.eye(4)
    m[1:3, 1:3] = [[ca, -sa], [sa, ca]]
    m[0, 3], m[2, 3] = float(model.a[i]), float(model.d[i])
    return m


def joint_origins(model: RobotModel) -> list[FloatArray]:
    """The origin (4 x 4) of each joint in its parent link's frame, then the flange's: joint
    ``i`` at ``A_{i-1} Rz(offset_i)`` (``A_k`` the fixed part of DH link ``k``, none before the
    first), the flange at ``A_n``; ``n + 1`` matrices."""
    out = []
    prev = np.eye(4)
    for i in range(model.n_joints):
        out.append(prev @ _rz(float(model.offset[i])))
        prev = _dh_link(model, i)
    out.append(prev)
    return out


def arm_transforms(model: RobotModel, q: npt.ArrayLike) -> list[FloatArray]:
    """Each link's pose in its parent's frame at the joint values ``q`` (rad): joint ``i``'s
    origin times ``Rz(q_i)``, ``n`` matrices 4 x 4 (the flange's is :func:`joint_origins`
    ``[-1]``, fixed)."""
    values = np.asarray(q, dtype=float).ravel()
    if values.shape[0] != model.n_joints:
        raise InvalidArgument(f"{model.name} has {model.n_joints} joints, got {values.shape[0]}")
    origins = joint_origins(model)
    return [origins[i] @ _rz(float(values[i])) for i in range(model.n_joints)]


def rpy(r: npt.ArrayLike) -> tuple[float, float, float]:
    """URDF's roll, pitch, yaw (rad) of a rotation matrix: ``R = Rz(yaw) Ry(pitch) Rx(roll)``
    (at pitch +-90 deg the yaw is 0 and the roll takes the whole turn about x)."""
    m = np.asarray(r, dtype=float)
    c = math.hypot(m[0, 0], m[1, 0])
    pitch = math.atan2(-m[2, 0], c)
    if c < _GIMBAL:
        return math.atan2(-m[1, 2], m[1, 1]), math.copysign(math.pi / 2, -m[2, 0]), 0.0
    return math.atan2(m[2, 1], m[2, 2]), pitch, math.atan2(m[1, 0], m[0, 0])


# -- XML -----------------------------------------------------------------------------------


def _num(v: float) -> str:
    v = float(v)
    return "0" if v == 0.0 else repr(v)  # repr: exact round trip (FK to 1e-9 m and better)


def _nums(values: Sequence[float]) -> str:
    return " ".join(_num(v) for v in values)


def _origin(parent: ET.Element, xyz: Sequence[float], angles: Sequence[float]) -> None:
    ET.SubElement(parent, "origin", xyz=_nums(xyz), rpy=_nums(angles))


def _visual(link: ET.Element, material: str, shape: str, size: dict[str, str],
            xyz: Sequence[float] = (0, 0, 0),
            angles: Sequence[float] = (0, 0, 0)) -> None:  # fmt: skip
    """A visual: what viewers draw (no collision shapes: nothing plans with these)."""
    part = ET.SubElement(link, "visual")
    _origin(part, xyz, angles)
    ET.SubElement(ET.SubElement(part, "geometry"), shape, size)
    ET.SubElement(part, "material", name=material)


def _segment(link: ET.Element, start: FloatArray, end: FloatArray, radius: float,
             material: str) -> None:  # fmt: skip
    """A cylinder from ``start`` to ``end`` (link frame, m); nothing for a zero length."""
    v = end - start
    length = float(np.linalg.norm(v))
    if length < 1e-9:
        return
    pitch = math.atan2(math.hypot(v[0], v[1]), v[2])
    yaw = math.atan2(v[1], v[0]) if math.hypot(v[0], v[1]) > 1e-12 else 0.0
    _visual(link, material, "cylinder", {"radius": _num(radius), "length": _num(length)},
            list((start + end) / 2), (0.0, pitch, yaw))  # fmt: skip


def _robot(name: str) -> ET.Element:
    root = ET.Element("robot", name=name)
    for material, rgba in (("grey", _GREY), ("orange", _ORANGE), ("black", _BLACK),
                           ("red", _RED)):  # fmt: skip
        ET.SubElement(ET.SubElement(root, "material", name=material), "color", rgba=rgba)
    return root


def _joint(root: ET.Element, name: str, kind: str, parent: str, child: str,
           origin: FloatArray) -> ET.Element:  # fmt: skip
    joint = ET.SubElement(root, "joint", name=name, type=kind)
    _origin(joint, list(origin[:3, 3]), rpy(origin[:3, :3]))
    ET.SubElement(joint, "parent", link=parent)
    ET.SubElement(joint, "child", link=child)
    return joint


def _text(root: ET.Element) -> str:
    ET.indent(root)
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _pose(x: float, y: float, z: float, yaw: float = 0.0, roll: float = 0.0) -> FloatArray:
    m = _rz(yaw)
    if roll:
        c, s = math.cos(roll), math.sin(roll)
        m = m @ np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])
    m[:3, 3] = (x, y, z)
    return m


def arm_urdf(model: RobotModel, prefix: str = "") -> str:
    """The URDF of a serial arm: links ``base``, ``link_1`` ... ``link_n``, ``flange``;
    revolute joints ``joint_1`` ... with the model's limits and speeds (see the module)."""
    root = _robot(model.name)
    origins = joint_origins(model)
    names = ["base", *(f"link_{i + 1}" for i in range(model.n_joints)), "flange"]
    links = [ET.SubElement(root, "link", name=prefix + n) for n in names]
    _visual(links[0], "grey", "cylinder", {"radius": _num(2 * _ARM_RADIUS), "length": "0.02"},
            (0, 0, 0.01))  # fmt: skip
    zero = np.zeros(3)
    for i in range(model.n_joints):
        link = links[i + 1]
        # the joint's actuator (along its axis), then the link out to the next joint's origin
        motor = {"radius": _num(round(_ARM_RADIUS * 1.1, 6)), "length": _num(3 * _ARM_RADIUS)}
        _visual(link, "orange", "cylinder", motor)
        corner = np.array([0.0, 0.0, float(model.d[i])])
        _segment(link, zero, corner, _ARM_RADIUS, "orange")
        _segment(link, corner, corner + [float(model.a[i]), 0.0, 0.0], _ARM_RADIUS, "orange")
        joint = _joint(root, f"joint_{i + 1}", "revolute", prefix + names[i],
                       prefix + names[i + 1], origins[i])  # fmt: skip
        ET.SubElement(joint, "axis", xyz="0 0 1")
        lo, hi = (float(v) for v in model.limits[i])
        ET.SubElement(joint, "limit", lower=_num(lo), upper=_num(hi), effort="0",
                      velocity=_num(float(model.max_speed[i])))  # fmt: skip
    _visual(links[-1], "black", "cylinder", {"radius": _num(_ARM_RADIUS), "length": "0.01"},
            (0, 0, -0.005))  # fmt: skip
    _joint(root, "flange_joint", "fixed", prefix + names[-2], prefix + names[-1], origins[-1])
    return _text(root)


def pioneer_urdf(params: RobotParams, prefix: str = "") -> str:
    """The URDF of a Pioneer: ``base_link`` (on the floor, at the centre of rotation, x
    forward) with the body and its caster, ``left_wheel`` and ``right_wheel`` (continuous
    joints at half the track that ``diff_conv`` gives), ``sonar_0`` ... at the sonar poses
    (each facing along its x), and ``laser`` at the laser mount."""
    p = params
    root = _robot(p.subtype)
    base = ET.SubElement(root, "link", name=prefix + "base_link")
    half = p.half_track
    r, w = p.wheel_radius, p.wheel_width
    bottom = r * 0.5
    length = p.length_front + p.length_rear
    body_w = max(2 * (half - w), 0.05)
    _visual(base, "red", "box",
            {"size": _nums((length, body_w, p.body_height - bottom))},
            ((p.length_front - p.length_rear) / 2, 0.0, (p.body_height + bottom) / 2))  # fmt: skip
    caster = bottom * 0.8
    _visual(base, "black", "sphere", {"radius": _num(caster / 2)},
            (-p.length_rear * 0.7, 0.0, caster / 2))  # fmt: skip
    for side, y in (("left", half), ("right", -half)):
        wheel = ET.SubElement(root, "link", name=f"{prefix}{side}_wheel")
        _visual(wheel, "black", "cylinder", {"radius": _num(r), "length": _num(w)},
                angles=(math.pi / 2, 0.0, 0.0))  # fmt: skip
        joint = _joint(root, f"{side}_wheel_joint", "continuous", prefix + "base_link",
                       f"{prefix}{side}_wheel", _pose(0.0, y, r))  # fmt: skip
        ET.SubElement(joint, "axis", xyz="0 1 0")
    ring = p.body_height - 0.03
    for i, s in enumerate(p.sonar):
        if s.x == 0.0 and s.y == 0.0:  # a slot the robot does not fit (PowerBot's 0, 0)
            continue
        sonar = ET.SubElement(root, "link", name=f"{prefix}sonar_{i}")
        _visual(sonar, "grey", "cylinder", {"radius": "0.02", "length": "0.01"},
                angles=(0.0, math.pi / 2, 0.0))  # fmt: skip
        _joint(root, f"sonar_{i}_joint", "fixed", prefix + "base_link", f"{prefix}sonar_{i}",
               _pose(s.x, s.y, ring, s.th))  # fmt: skip
    m = p.laser_mount
    laser = ET.SubElement(root, "link", name=prefix + "laser")
    _visual(laser, "black", "cylinder", {"radius": "0.03", "length": "0.05"})
    _joint(root, "laser_joint", "fixed", prefix + "base_link", prefix + "laser",
           _pose(m.x, m.y, p.body_height + 0.035, m.th, math.pi if m.flipped else 0.0))  # fmt: skip
    return _text(root)
