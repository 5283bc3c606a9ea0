"""Serial-arm kinematics: robot models from shipped JSON files, vectorised forward
kinematics, the geometric Jacobian, inverse kinematics, trajectories and validation.

>>> from robocli.kinematics import load_model, fk_positions
>>> model = load_model("irb120")
>>> fk_positions(model, model.home)[0]      # doctest: +SKIP
array([0.374, 0.   , 0.63 ])
"""

from __future__ import annotations

from robocli.kinematics.errors import (
    KinematicsError,
    LimitError,
    ModelFileError,
    UnknownModelError,
    UnreachableError,
)
from robocli.kinematics.fk import fk, fk_positions, jacobian
from robocli.kinematics.ik import analytic_solutions, dls, ik, ik_path
from robocli.kinematics.model import RobotModel, known_models, load_model

__all__ = [
    "KinematicsError",
    "LimitError",
    "ModelFileError",
    "RobotModel",
    "UnknownModelError",
    "UnreachableError",
    "analytic_solutions",
    "dls",
    "fk",
    "fk_positions",
    "ik",
    "ik_path",
    "jacobian",
    "known_models",
    "load_model",
]
