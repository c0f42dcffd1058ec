"""Cassie's feet placed by inverse kinematics, the four leg loops held.

Cassie (example-robot-data's SDF, read by :mod:`hexapod_pin.loaders.sdf`) hangs from its
pelvis; each leg has two loops closed by ball joints (the achilles and the plantar rods,
see ``examples/cassie_leg.py``). With its knee and heel springs held rigid, the script
places both feet at once at footstep targets (positions only: a leg has four motors left
once the springs are rigid, and its achilles loop then holds the knee, so the targets are
taken where swinging hips put the feet). It solves one
ProxSuite QP per step over all 22 tree joints with the 12 closure rows (rank 10) as
equalities, closes the loops again after each step, and prints the motor angles, the
residuals and the iterations. A second call weights the right foot 4x more and asks for
a target out of its reach: the closest placement comes back, flagged.

Usage::

    python examples/cassie_foot_placement.py
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from hexapod_pin.loaders import robots

FEET = ("left-foot", "right-foot")


def main() -> None:
    np.set_printoptions(precision=4, suppress=True)
    cassie = robots.cassie(root="fixed")
    springs = [f"{side}-{j}" for side in ("left", "right")
               for j in ("knee-shin-joint", "tarsus-spring-joint")]
    q0 = pin.neutral(cassie.model)
    for side in ("left", "right"):
        q0[cassie.joint_q_index(f"{side}-pitch-op")] = 0.3
        q0[cassie.joint_q_index(f"{side}-foot-op")] = -0.4
    held = np.r_[cassie.actuated_v, [cassie.joint_v_index(s) for s in springs]]
    q = cassie.assemble(q0, fixed=held).q
    pin.framesForwardKinematics(cassie.model, cassie.data, q)
    feet = [cassie.data.oMf[cassie.frame_id(f)].translation.copy() for f in FEET]
    print(f"Cassie (fixed pelvis): nv={cassie.nv}, {cassie.n_rows} closure rows "
          f"(rank {cassie.rank(q).rank}); feet at {feet[0]} and {feet[1]} m")

    # footstep targets: where the feet go when the hips swing (a leg whose springs are
    # rigid keeps its hip-to-foot length: its achilles loop holds the knee)
    q_swing = q.copy()
    for joint, angle in (("left-pitch-op", 0.15), ("left-roll-op", 0.05),
                         ("right-pitch-op", -0.1), ("right-yaw-op", 0.1)):
        q_swing[cassie.joint_q_index(joint)] += angle
    q_swing = cassie.assemble(q_swing, fixed=held).q
    pin.framesForwardKinematics(cassie.model, cassie.data, q_swing)
    targets = [cassie.data.oMf[cassie.frame_id(f)].translation.copy() for f in FEET]
    print(f"targets {targets[0]} and {targets[1]} m")
    # this start has the foot motors outside the SDF's ranges: joint limits off
    res = cassie.frame_inverse_kinematics(FEET, targets, q, position_only=True, fixed=springs,
                                          limits=False)
    print(f"both feet placed: reachable={res.reachable} in {res.iterations} iterations, "
          f"target residual {res.target_residual:.1e} m, closures {res.closure_residual:.1e} m")
    motors = [cassie.joint_q_index(j) for j in cassie.actuated_joints]
    print(f"motor angles {res.q[motors]} rad\n      (were {q[motors]})")

    far = [targets[0], feet[1] + [0.0, 0.0, 0.5]]
    closest = cassie.frame_inverse_kinematics(FEET, far, res.q, position_only=True,
                                              fixed=springs, weights=[1.0, 4.0], limits=False)
    print(f"right foot 50 cm up: reachable={closest.reachable}; closest right foot "
          f"{closest.placements[1].translation} m ({closest.target_residual:.3f} m short), "
          f"closures {closest.closure_residual:.1e} m")


if __name__ == "__main__":
    main()
