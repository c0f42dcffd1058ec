"""Cassie's closed kinematic loops: read the SDF, close the rods, assemble, dynamics.

example-robot-data ships Cassie as an SDF (``cassie_description/robots/cassie_v2.sdf``),
and Pinocchio's wheel has no SDF reader; :mod:`hexapod_pin.loaders.sdf` reads it. Each leg has
two loops, each closed in the SDF by a ball joint:

* the achilles rod: hip-pitch -> knee -> shin -> tarsus -> heel spring -> achilles rod,
  back to hip-pitch through ``{side}-pitch-rod-joint`` (ball);
* the plantar rod: tarsus -> foot crank -> plantar rod, back to the foot through
  ``{side}-plantar-foot-joint`` (ball), the foot also hinged on the tarsus.

The reader keeps the 22 revolute joints in a depth-first tree and turns each ball joint
into a 3-D point closure (a ball joint *is* a point-on-point constraint). The plantar
loop is planar, so one of its three rows is implied by the other two: 12 rows, rank 10.

The robot hangs from its pelvis (fixed at its SDF pose, 1.01 m up). The script
assembles it with the hip and knee motors moved, reports the mobility and actuation,
then runs the constrained forward dynamics under gravity, the knee / heel springs of
the SDF and some motor torques, and recovers those torques by closed-loop inverse
dynamics.

Usage::

    python examples/cassie_leg.py
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import scipy.linalg

from hexapod_pin.loaders import robots
from hexapod_pin.core.dynamics import forward_dynamics_tree, inverse_dynamics_tree


def main() -> None:
    np.set_printoptions(precision=4, suppress=True)
    cassie = robots.cassie(root="fixed")
    print(f"Cassie (fixed pelvis): nq={cassie.nq} nv={cassie.nv}, closures:")
    for closure in cassie.closures:
        print(f"  {closure.name:26s} {closure.type}: {closure.frame1} on {closure.frame2}")

    # move the hip pitch and foot motors of both legs; the plantar loops close again
    q0 = pin.neutral(cassie.model)
    for side in ("left", "right"):
        q0[cassie.joint_q_index(f"{side}-pitch-op")] = 0.3
        q0[cassie.joint_q_index(f"{side}-foot-op")] = -0.4
    springs_v = [cassie.joint_v_index(f"{side}-{j}") for side in ("left", "right")
                 for j in ("knee-shin-joint", "tarsus-spring-joint")]
    result = cassie.assemble(q0, fixed=np.r_[cassie.actuated_v, springs_v])  # springs at rest
    q = result.q
    print(f"assembled in {result.iterations} iterations, closure residual "
          f"{result.residual_norm:.1e} m")
    # in this SDF the achilles rod is hinged (revolute) at the heel, so with rigid springs
    # its loop leaves the knee no motion: moving the knee motor deflects the springs
    q_knee = q.copy()
    q_knee[cassie.joint_q_index("left-knee-op")] = -0.2
    q_knee = cassie.assemble(q_knee).q
    deflection = [q_knee[cassie.joint_q_index(n)] for n in
                  ("left-knee-shin-joint", "left-tarsus-spring-joint")]
    print(f"knee motor at -0.2 rad: knee / heel spring deflections {np.round(deflection, 4)} rad")
    report = robots.actuation_report(cassie, q)
    print(f"rank J_c = {report.rank} of {report.n_rows} rows ({report.redundant_rows} "
          f"redundant), mobility {report.mobility}, {report.n_actuated} actuators: "
          f"{report.status} ({report.unactuated_mobility} passive DoF: the springs)")

    # a closure-consistent velocity, then forward dynamics with springs and motor torques
    rng = np.random.default_rng(0)
    null = scipy.linalg.null_space(cassie.constraint_jacobian(q), rcond=1e-9)
    v = 0.1 * null @ rng.normal(size=null.shape[1])
    springs = robots.cassie_spring_torques(cassie, q)
    u = rng.uniform(-0.5, 0.5, cassie.n_actuated)
    fd = forward_dynamics_tree(cassie, q, v, u, tau_ext=springs, method="kkt")
    drift = cassie.constraint_drift(q, v)
    print(f"forward dynamics: max |a| = {np.abs(fd.a).max():.3g}, "
          f"|J_c a + gamma| = {np.abs(cassie.constraint_jacobian(q) @ fd.a + drift).max():.1e}")
    inv = inverse_dynamics_tree(cassie, q, v, fd.a, tau_ext=springs, method="kkt")
    print(f"inverse dynamics recovers the motor torques to "
          f"{np.abs(inv.actuator_forces - u).max():.1e} N m")
    print(f"closure forces at the ball joints (N, world axes):\n"
          f"{fd.multipliers.reshape(4, 3)}")


if __name__ == "__main__":
    main()
