"""What a type checker sees of the robot facades: type-checked by mypy (``[tool.mypy]`` in
pyproject.toml, run by ``tests/test_docs.py``), never run.

Each robot is a :class:`~hexapod_pin.core.robot_api.ParallelRobot`, and each facade method
made by :class:`~hexapod_pin.core.robot_api.delegate` has the component's signature: the
lines marked ``# type: ignore[...]`` are wrong calls that mypy must reject
(``warn_unused_ignores`` makes an ignore that is not needed an error, so a facade whose
methods lost their types fails the check).
"""

from __future__ import annotations

import numpy as np

from hexapod_pin import Hexapod, Planar3PRR
from hexapod_pin.core.results import ForwardDynamicsResult, InverseDynamicsResult
from hexapod_pin.core.robot_api import ParallelRobot
from hexapod_pin.hexapod.dynamics import HexapodDynamics


def shared(robot: ParallelRobot) -> InverseDynamicsResult:
    pose = robot.home_pose
    return robot.inverse_dynamics(pose, np.zeros(robot.pose_dim), np.zeros(robot.pose_dim))


def facades() -> None:
    hexapod, planar = Hexapod.default(), Planar3PRR.default()
    shared(hexapod)
    shared(planar)
    res: InverseDynamicsResult = hexapod.inverse_dynamics([0, 0, 0.5, 0, 0, 0], [0] * 6, [0] * 6)
    fwd: ForwardDynamicsResult = planar.forward_dynamics([0, 0, 0], [0, 0, 0], [0, 0, 0])
    forces: np.ndarray = hexapod.static_forces(hexapod.home_pose, bounded=False)
    del res, fwd, forces
    # the class attribute is the component's function (self first)
    HexapodDynamics.inverse_dynamics(hexapod.dynamics, hexapod.home_pose, [0] * 6, [0] * 6)
    Hexapod.inverse_dynamics(hexapod.dynamics, hexapod.home_pose, [0] * 6, [0] * 6)


def wrong_calls() -> None:
    hexapod, planar = Hexapod.default(), Planar3PRR.default()
    pose = hexapod.home_pose
    hexapod.inverse_dynamics(pose, [0] * 6, [0] * 6, method=3)  # type: ignore[arg-type]
    hexapod.jacobian(pose, brunch=None)  # type: ignore[call-arg]
    planar.static_forces(planar.home_pose, bounded="yes")  # type: ignore[arg-type]
    wrong: str = hexapod.singularity(pose)  # type: ignore[assignment]
    del wrong
