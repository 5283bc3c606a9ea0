"""An arm's state as ``connect arm`` shows it: the last state as JSON-ready data (joints,
TCP pose, status; ``t`` in Unix time) and as one terminal line, and the stream of them."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

from robocli.io.jsonlines import unix_stamped

if TYPE_CHECKING:
    from robocli.devices.arm import Arm

__all__ = ["describe", "state_text", "states"]

#: The status flags a text line shows when set, and their words there.
_FLAGS = {"drives_powered": "powered", "motion_possible": "ready", "in_motion": "moving",
          "in_error": "ERROR", "e_stopped": "E-STOP"}  # fmt: skip


def describe(arm: Arm) -> dict[str, Any]:
    """Joints (deg and rad), TCP pose (flange position in m, roll-pitch-yaw in deg) and
    status of the last state; ``t`` its receive time as Unix time (``t_mono``: on
    ``time.monotonic()``), ``robot_time`` the controller's."""
    from robocli.kinematics.fk import fk

    sample = arm.joints
    assert sample is not None
    pose = fk(arm.robot, list(sample.joints))[0]
    r = pose[:3, :3]  # Z-Y-X Euler angles (yaw about z, pitch about y, roll about x)
    rpy = (math.atan2(r[2, 1], r[2, 2]), math.asin(max(-1.0, min(1.0, -r[2, 0]))),
           math.atan2(r[1, 0], r[0, 0]))  # fmt: skip
    st = arm.status
    return {
        **unix_stamped({"t": sample.t}), "robot_time": sample.robot_time,
        "joints_rad": list(sample.joints),
        "joints_deg": sample.degrees(), "tcp_m": [float(v) for v in pose[:3, 3]],
        "tcp_rpy_deg": [math.degrees(v) for v in rpy],
        "status": st.as_dict() if st is not None else None,
    }  # fmt: skip


def state_text(d: dict[str, Any]) -> str:
    """One :func:`describe` in one terminal line (under 100 characters): joints (deg), TCP
    (m) and roll-pitch-yaw (deg), and only the status flags that are set."""
    deg = " ".join(f"{v:.1f}" for v in d["joints_deg"])
    x, y, z = d["tcp_m"]
    roll, pitch, yaw = d["tcp_rpy_deg"]
    st = d["status"] or {}
    flags = [word for key, word in _FLAGS.items() if st.get(key) is True]
    flags += [str(st["mode"])] if st.get("mode") else []
    flags += [f"error {st['error_code']}"] if st.get("error_code") else []
    return (
        f"deg [{deg}]  tcp {x:.3f} {y:.3f} {z:.3f} m  rpy {roll:.0f} {pitch:.0f} {yaw:.0f}"
        f"  {' '.join(flags)}"
    )


def states(arm: Arm, timeout: float = 5.0) -> Iterator[dict[str, Any]]:
    """:func:`describe` of each state the arm sends, from the first (waited for) on; a state
    that does not come within ``timeout`` s is a :class:`~robocli.errors.TimeoutError`."""
    arm.wait_for_state()
    while True:
        yield describe(arm)
        arm.wait_for_state(timeout)
