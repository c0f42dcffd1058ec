"""A delta robot's end effector to a target, its three parallelogram-free legs closed.

The delta of ``tests/data/parallel/delta`` (example-parallel-robots format: a URDF tree
plus ``robot.yaml``) has three motors and 6-D weld closures where its legs meet the
platform: 12 closure rows for a 3-DoF translating platform. The script

(a) assembles it with the motors at 0.5 rad;
(b) moves the platform centre 3 cm by frame-target inverse kinematics with the closures
    held (one ProxSuite QP per step, the closure rows as equalities, the joint limits
    as bounds), and prints the motor angles, the residuals and the iterations;
(c) maps motor velocities to the platform velocity there (``frame_jacobian_from_actuated``);
(d) asks for a tilted platform, which a delta cannot give: the closest reachable
    placement comes back, flagged ``reachable=False``, its position on the target;
(e) folds the legs (forearms bent back along the upper arms, the platform above the base)
    and asks for a point 2 cm lower, out of reach from there: the closest placement comes
    back flagged, in a few steps.

Usage::

    python examples/delta_end_effector.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin

from hexapod_pin.loaders.parallel_robots import load_parallel_robot

DELTA = Path(__file__).resolve().parent.parent / "tests" / "data" / "parallel" / "delta"


def main() -> None:
    np.set_printoptions(precision=5, suppress=True)
    delta = load_parallel_robot(DELTA)
    q0 = delta.neutral()
    for k in range(3):                       # motors at 0.5 rad, elbows bent, platform below
        q0[delta.joint_q_index(f"motor_{k}")] = 0.5
        q0[delta.joint_q_index(f"elbow_{k}_Y")] = 1.9
        q0[delta.joint_q_index(f"wrist_{k}_Y")] = -2.4
    q = delta.assemble(q0).q
    motors = [delta.joint_q_index(f"motor_{k}") for k in range(3)]
    pin.framesForwardKinematics(delta.model, delta.data, q)
    centre = delta.data.oMf[delta.frame_id("platform_center")].translation.copy()
    print(f"delta: nv={delta.nv}, {delta.n_rows} closure rows (rank {delta.rank(q).rank}), "
          f"mobility {delta.mobility(q)}; platform centre at {centre} m")

    target = centre + np.array([0.02, -0.01, -0.02])
    res = delta.frame_inverse_kinematics("platform_center", target, q, position_only=True)
    print(f"target {target} m: reachable={res.reachable} in {res.iterations} iterations, "
          f"target residual {res.target_residual:.1e} m, closures {res.closure_residual:.1e} m")
    print(f"motor angles {res.q[motors]} rad (were {q[motors]})")

    jac = delta.frame_jacobian_from_actuated(res.q, "platform_center")
    print(f"platform velocity per unit motor speed (m/s per rad/s, world axes):\n{jac[:3]}")
    print(f"platform angular velocity from any motor speed: max {np.abs(jac[3:]).max():.1e}")

    here = pin.SE3(res.placements[0])
    tilted = pin.SE3(here.rotation @ pin.rpy.rpyToMatrix(0.1, 0.0, 0.0), here.translation)
    closest = delta.frame_inverse_kinematics("platform_center", tilted, res.q)
    miss = closest.placements[0].translation - tilted.translation
    print(f"tilted target: reachable={closest.reachable}; closest placement at "
          f"{np.abs(miss).max():.1e} m from the target position, orientation error "
          f"{closest.target_residual:.3f} rad (the tilt a delta cannot make)")

    folded = delta.neutral()
    for k in range(3):                       # forearms folded back: the platform above the base
        folded[delta.joint_q_index(f"motor_{k}")] = 1.2
        folded[delta.joint_q_index(f"elbow_{k}_Y")] = 2.6
        folded[delta.joint_q_index(f"wrist_{k}_Y")] = -3.0
    folded = delta.assemble(folded).q
    pin.framesForwardKinematics(delta.model, delta.data, folded)
    top = delta.data.oMf[delta.frame_id("platform_center")].translation.copy()
    below = delta.frame_inverse_kinematics("platform_center", top - [0.0, 0.0, 0.02], folded,
                                           position_only=True)
    print(f"folded legs, target 2 cm below {top} m: reachable={below.reachable} after "
          f"{below.iterations} iterations, closest placement "
          f"{np.linalg.norm(below.errors) * 1e3:.2f} mm from it, closures "
          f"{below.closure_residual:.1e} m")


if __name__ == "__main__":
    main()
