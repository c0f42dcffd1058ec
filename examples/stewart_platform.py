"""A Gough-Stewart platform (6-UPS) that the library has no code for, end to end.

Loads ``tests/data/stewart/stewart.urdf`` (its loops file names the platform, the pose
axes and the home configuration), then: inverse kinematics checked against the leg
lengths ``|p + R b_i - a_i|``, the Jacobian and the conditioning of a pose, inverse and
forward dynamics of a motion, the statics of a payload, a free fall of 0.2 s with its
energy balance, and a time-optimal motion through three waypoints. Prints each result.

Usage::

    python examples/stewart_platform.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import hexapod_pin as hp
from hexapod_pin.core.pose import rotation_from_rpy
from hexapod_pin.planning import Limits, time_optimal

DATA = Path(__file__).resolve().parents[1] / "tests" / "data" / "stewart"
# base and platform points (tests/data/stewart/README.md), leg length = q + 0.65 m
ALPHA, BETA = np.deg2rad([-15, 15, 105, 135, 225, 255]), np.deg2rad([-45, 45, 75, 165, 195, 285])
BASE = 0.5 * np.c_[np.cos(ALPHA), np.sin(ALPHA), np.zeros(6)]
PLATFORM = 0.3 * np.c_[np.cos(BETA), np.sin(BETA), np.zeros(6)]


def main() -> None:
    robot = hp.load_robot(DATA / "stewart.urdf")
    print(robot, "home", robot.home_pose)
    pose = robot.home_pose + np.array([0.02, -0.01, 0.03, 0.05, -0.04, 0.1])
    legs = robot.inverse_kinematics(pose)
    closed_form = np.linalg.norm(pose[:3] + PLATFORM @ rotation_from_rpy(pose[3:]).T - BASE,
                                 axis=1) - 0.65
    print("leg extensions (m)", legs, "closed form miss", np.abs(legs - closed_form).max())
    measures = robot.singularity(pose)
    print("cond(J)", measures.condition_number, "type I / II", measures.type_one,
          measures.type_two)
    twist, twist_dot = np.array([0.05, 0, -0.02, 0.1, 0, 0.2]), np.array([0.5, 0, 0, 0, 1, 0])
    res = robot.inverse_dynamics(pose, twist, twist_dot)
    back = robot.forward_dynamics(pose, twist, res.actuator_forces)
    print("leg forces (N)", res.actuator_forces, "FD(ID) miss",
          np.abs(back.twist_dot - twist_dot).max())
    print("statics with a 5 kg payload (N)",
          robot.static_forces(pose, [0, 0, -5 * 9.81, 0, 0, 0]))
    run = hp.simulate(robot, duration=0.2, dt=1e-3)
    balance = np.abs(run.energies - run.energies[0]).max()
    print("free fall:", run.status, "platform z", run.poses[-1, 2], "energy drift (J)", balance)
    waypoints = robot.home_pose + np.array([[0, 0, 0, 0, 0, 0], [0.03, 0, 0.02, 0, 0.05, 0],
                                            [0.05, 0.03, 0, 0, 0, 0.1]])
    plan = time_optimal(robot, waypoints, limits=Limits(actuator_force=400.0),
                        grid_points=200)
    print("time-optimal: duration (s)", plan.t[-1], "max |force| (N)",
          np.abs(plan.actuator_forces).max())


if __name__ == "__main__":
    main()
