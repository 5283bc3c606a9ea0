"""The textbook reference of forward kinematics: per pose, the product of 4x4 standard DH
matrices (what robocli's vectorised ``fk`` is checked against, and timed against in bench/)."""

from __future__ import annotations

import math

import numpy as np

from robocli.kinematics.model import RobotModel


def dh_product(model: RobotModel, q: np.ndarray) -> np.ndarray:
    """The 4x4 pose of ``model``'s flange at joint angles ``q`` (one pose), slowly."""
    out = np.eye(4)
    for i in range(model.n_joints):
        th = q[i] + model.offset[i]
        ct, st = math.cos(th), math.sin(th)
        ca, sa = math.cos(model.alpha[i]), math.sin(model.alpha[i])
        out = out @ np.array(
            [
                [ct, -st * ca, st * sa, model.a[i] * ct],
                [st, ct * ca, -ct * sa, model.a[i] * st],
                [0.0, sa, ca, model.d[i]],
                [0.0, 0.0, 0.0, 1.0],
            ]
        )
    return out
