"""The hexapod's platform placed by the generic closed-loop route, checked by its closed form.

The hexapod is one instance of a generic closed-loop model: a Pinocchio tree (six
carriages on rails, six legs on universal joints, the platform as a free flyer) with six
3-D point closures joining the leg tips to the platform. The generic frame-target inverse
kinematics (ProxSuite QP per step, closures as equalities, carriage strokes as bounds)
knows nothing of rails or legs; the hexapod's closed form
(:meth:`hexapod_pin.Hexapod.inverse_kinematics`) solves each leg by a quadratic. The
script places the platform at a pose both ways and compares the carriage positions, then
the generic workspace Jacobian with the inverse of the closed-form one.

Usage::

    python examples/hexapod_platform_generic_ik.py
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

import hexapod_pin as hp


def main() -> None:
    np.set_printoptions(precision=6, suppress=True)
    robot = hp.Hexapod.default()
    clm = robot.model
    pose = robot.home_pose + np.array([0.01, -0.015, -0.01, 0.05, -0.04, 0.08])
    target = pin.SE3(pin.rpy.rpyToMatrix(*pose[3:]), pose[:3])

    res = clm.frame_inverse_kinematics("platform", target, robot.home_configuration)
    generic = res.q[robot.indices.carriage_q]
    closed = robot.inverse_kinematics(pose)
    print(f"pose {pose} (m, rad)")
    print(f"generic route: reachable={res.reachable} in {res.iterations} iterations, "
          f"target residual {res.target_residual:.1e}, closures {res.closure_residual:.1e} m")
    print(f"carriages, generic     {generic} m")
    print(f"carriages, closed form {closed} m")
    print(f"largest difference {np.abs(generic - closed).max():.1e} m")

    jac_generic = clm.frame_jacobian_from_actuated(res.q, "platform")
    jac_closed = robot.jacobian(pose)
    print(f"workspace Jacobian: |K J - I| = {np.abs(jac_generic @ jac_closed - np.eye(6)).max():.1e}"
          " (K generic, J closed form)")


if __name__ == "__main__":
    main()
