"""Solo-12 standing on its four feet: assembly, closed-loop inverse dynamics, forward dynamics.

Solo-12 comes from example-robot-data (its URDF, read from the installed package, no
network), with a free-flyer base. Each foot is held at a point of the ground by a 3-D
point closure to the world (a contact as a holonomic closure). The script

(a) assembles a standing configuration with the base at a chosen pose: the 6 base
    coordinates are held, the 12 leg joints are solved (Gauss-Newton);
(b) computes the 12 joint torques that hold the robot still, then those that give the
    base a chosen acceleration with the feet fixed: closed-loop inverse dynamics on the
    generic core (the free-flyer is not actuated), as a ProxSuite QP with torque bounds;
(c) runs the constrained forward dynamics with those torques and checks that the base
    acceleration comes back.

Why a QP: the equation of motion ``M a + h = S^T u + J_c^T lambda`` has 18 rows
(6 base + 12 joints) and 24 unknowns (12 torques u, 12 contact-force components lambda):
with the feet fixed the robot is *redundantly* actuated (6 more actuators than the 6 DoF
left to the base), and a 6-dimensional family of torques (internal forces between the
feet, squeezing or pulling the ground) produces the same motion. The QP picks the one of
least ``|u|^2`` (the contact forces are weighted 1e-8, which only matters for redundant
closure rows), within the bounds. The contact forces are bilateral (no friction cone or
unilaterality is imposed); they are printed so that one can see they are reasonable.

Usage::

    python examples/solo12_standing.py
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from hexapod_pin.loaders import robots
from hexapod_pin.core.dynamics import forward_dynamics_tree, inverse_dynamics_tree


def main() -> None:
    np.set_printoptions(precision=4, suppress=True)
    solo = robots.solo12()                                   # feet under the SRDF stance
    report = robots.actuation_report(solo, robots.solo12_reference_configuration())
    print(f"Solo-12: nq={solo.nq} nv={solo.nv}, {solo.n_rows} closure rows, "
          f"{solo.n_actuated} actuated joints")

    # (a) the base 0.20 m above the ground, pitched and yawed a little
    result = robots.solo12_stand(solo, base_position=[0.0, 0.0, 0.20],
                                 base_rpy=[0.0, 0.05, 0.1])
    q = result.q
    report = robots.actuation_report(solo, q)
    print(f"(a) assembled in {result.iterations} iterations, closure residual "
          f"{result.residual_norm:.1e} m")
    print(f"    leg joints (rad): {q[7:]}")
    print(f"    mobility {report.mobility} (nv - rank J_c = {report.nv} - {report.rank}), "
          f"{report.n_actuated} actuators: {report.status} "
          f"(redundancy {report.actuation_redundancy})")

    # (b) holding still
    mass = sum(solo.model.inertias[j].mass for j in range(solo.model.njoints))
    v, a = robots.motion_with_base(solo, q, np.zeros(6), np.zeros(6))
    still = inverse_dynamics_tree(solo, q, v, a, bounds=robots.SOLO12_TORQUE_LIMIT)
    forces = still.multipliers.reshape(4, 3)
    print(f"(b) torques holding it still (N m): {still.actuator_forces}")
    print(f"    contact forces on the feet (N, world axes):\n{forces}")
    print(f"    sum of vertical contact forces {forces[:, 2].sum():.6f} N, "
          f"m g = {mass * 9.81:.6f} N")

    #     a base motion with the feet fixed: moving up and yawing
    v_base = np.array([0.0, 0.0, 0.05, 0.0, 0.0, 0.2])      # body frame (m/s, rad/s)
    a_base = np.array([0.1, 0.0, 1.0, 0.0, 0.5, 2.0])       # d/dt of it (m/s^2, rad/s^2)
    v, a = robots.motion_with_base(solo, q, v_base, a_base)
    moving = inverse_dynamics_tree(solo, q, v, a, bounds=robots.SOLO12_TORQUE_LIMIT)
    print(f"    torques for base acceleration {a_base}: {moving.actuator_forces} "
          f"(bound {robots.SOLO12_TORQUE_LIMIT} N m)")

    # (c) constrained forward dynamics of those torques
    for method in ("pinocchio", "qp", "kkt"):
        fd = forward_dynamics_tree(solo, q, v, moving.actuator_forces, method=method)
        err = np.max(np.abs(fd.a[:6] - a_base))
        print(f"(c) forward dynamics ({method:9s}): base acceleration error {err:.1e}")
    data = solo.model.createData()
    pin.centerOfMass(solo.model, data, q, v, a)
    print(f"    Newton: sum of contact forces {moving.multipliers.reshape(4, 3).sum(0)} N = "
          f"m (c_ddot - g) = {mass * (data.acom[0] - solo.model.gravity.linear)} N")


if __name__ == "__main__":
    main()
